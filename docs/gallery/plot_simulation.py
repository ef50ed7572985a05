"""
A simulation at a glance
========================

Everything ``skewpend simulate --plot`` draws in one figure (``skewpend.views.figures.simulation_figure``):
angles, speeds and the energy error against time, both phase portraits, the path on the
configuration torus and the 3D paths of the rod ends — here for the reference case over 20 s.
"""

import skewpend
from skewpend.views.figures import simulation_figure

params = skewpend.reference_parameters()
tr = skewpend.simulate(params, skewpend.reference_state(), 20.0, dt_out=0.01)
fig = simulation_figure(tr)

# fig.savefig("figure.png") writes it to a file (.png, .svg or .pdf): a Matplotlib figure
