"""
The rod ends in 3D
==================

The paths of the ends of both rods of the reference case over 10 s, with the rods at the start
(``skewpend.views.figures.tips_figure``). Because the second hinge is skewed by α = 0.6 rad, rod 2
swings out of the plane of rod 1: the paths are not flat.
"""

import skewpend
from skewpend.views.figures import tips_figure

params = skewpend.reference_parameters()
tr = skewpend.simulate(params, skewpend.reference_state(), 10.0, dt_out=0.01)
fig = tips_figure(tr)

# fig.savefig("figure.png") writes it to a file (.png, .svg or .pdf): a Matplotlib figure
