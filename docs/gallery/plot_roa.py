"""
Region of attraction of a saturated LQR
=======================================

The reference pendulum balanced upright by the LQR with both joints actuated and at most
10 N m per motor: every start at rest on a 96 × 96 grid of (φ, ψ) about the target, followed
for 10 s, coloured by when it entered the LQR's own inner estimate (the ellipse); light grey:
not captured by then (``skewpend.region_of_attraction`` and
``skewpend.views.figures.roa_figure``). The captured region is far larger than the estimate.
"""

import skewpend
from skewpend.views.figures import roa_figure

params = skewpend.reference_parameters()
roa = skewpend.region_of_attraction(params, "up-up", "both", 96, umax=10.0)
fig = roa_figure(roa)

# fig.savefig("figure.png") writes it to a file (.png, .svg or .pdf): a Matplotlib figure
