"""
Normal modes against the skew angle
===================================

The two small-oscillation frequencies of the reference pendulum as the skew angle α goes from
0° to 180°, with the direction of each mode shape in the (φ, ψ) plane
(``skewpend.sweep`` and ``skewpend.views.figures.plot_sweep``). The dashed lines mark where the
upper frequency is twice the lower one: a 2:1 internal resonance.
"""

import numpy as np

import skewpend
from skewpend.views.figures import plot_sweep

params = skewpend.reference_parameters()
sw = skewpend.sweep(params, "alpha", np.radians(np.linspace(0.0, 180.0, 181)))
fig = plot_sweep(sw)

# fig.savefig("figure.png") writes it to a file (.png, .svg or .pdf): a Matplotlib figure
