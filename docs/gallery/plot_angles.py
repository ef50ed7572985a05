"""
Angles and speeds against time
==============================

The two hinge angles φ and ψ (unwrapped, in degrees) and their rates of the reference case —
the rods released at rest from φ = 1.2 rad, ψ = −0.8 rad with the hinges skewed by α = 0.6 rad —
over 20 s (``skewpend.views.figures.angles_figure``).
"""

import skewpend
from skewpend.views.figures import angles_figure

params = skewpend.reference_parameters()
tr = skewpend.simulate(params, skewpend.reference_state(), 20.0, dt_out=0.01)
fig = angles_figure(tr)

# fig.savefig("figure.png") writes it to a file (.png, .svg or .pdf): a Matplotlib figure
