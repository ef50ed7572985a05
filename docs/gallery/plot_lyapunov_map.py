"""
Lyapunov map
============

The largest Lyapunov exponent of the reference pendulum released at rest from each of
32 × 32 starts (φ0, ψ0), over 50 s (``skewpend.lyapunov_map`` and
``skewpend.views.figures.lyapunov_map_figure``). Dark: regular motion, near the hanging
position; bright: chaos, for starts high enough to come near going over the top.
"""

import skewpend
from skewpend.views.figures import lyapunov_map_figure

params = skewpend.reference_parameters()
lmap = skewpend.lyapunov_map(params, 32, t_end=50.0)
fig = lyapunov_map_figure(lmap)

# fig.savefig("figure.png") writes it to a file (.png, .svg or .pdf): a Matplotlib figure
