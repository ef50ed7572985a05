"""
Energy error
============

How well the integrator keeps the energy: the relative error ``|E − W − E0| / max|E|`` of the
reference case over 20 s, for DOP853 at its default tolerance 1e-10
(``skewpend.views.figures.energy_figure``; ``W`` is the work of damping and torques, zero here).
"""

import skewpend
from skewpend.views.figures import energy_figure

params = skewpend.reference_parameters()
tr = skewpend.simulate(params, skewpend.reference_state(), 20.0, dt_out=0.01)
fig = energy_figure(tr)

# fig.savefig("figure.png") writes it to a file (.png, .svg or .pdf): a Matplotlib figure
