"""
The path on the configuration torus
===================================

The configuration (φ, ψ) of the reference case over 20 s, both angles wrapped to ±180°: the
square's opposite edges are the same configuration, so the path lives on a torus and is cut
where it wraps (``skewpend.views.figures.torus_figure``).
"""

import skewpend
from skewpend.views.figures import torus_figure

params = skewpend.reference_parameters()
tr = skewpend.simulate(params, skewpend.reference_state(), 20.0, dt_out=0.01)
fig = torus_figure(tr)

# fig.savefig("figure.png") writes it to a file (.png, .svg or .pdf): a Matplotlib figure
