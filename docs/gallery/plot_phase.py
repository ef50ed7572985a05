"""
Phase portraits
===============

Each joint's angle (wrapped to ±180°) against its speed for the reference case over 20 s
(``skewpend.views.figures.phase_figure``). The tangled curves are a first sign of chaos: a
regular motion would trace a closed band.
"""

import skewpend
from skewpend.views.figures import phase_figure

params = skewpend.reference_parameters()
tr = skewpend.simulate(params, skewpend.reference_state(), 20.0, dt_out=0.01)
fig = phase_figure(tr)

# fig.savefig("figure.png") writes it to a file (.png, .svg or .pdf): a Matplotlib figure
