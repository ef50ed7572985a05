"""
Flip-time map
=============

How long the reference pendulum, released at rest from (φ0, ψ0), takes until either hinge angle
first leaves (−180°, 180°) — over 160 × 160 starts and 10 s (``skewpend.flip_map`` and
``skewpend.views.figures.flipmap_figure``). White: no flip within 10 s; grey: energy forbids
any flip; the dot is the reference start.
"""

import skewpend
from skewpend.views.figures import flipmap_figure

params = skewpend.reference_parameters()
fm = skewpend.flip_map(params, 160, t_end=10.0)
fig = flipmap_figure(fm, mark=skewpend.reference_state()[:2], mark_label="reference start")

# fig.savefig("figure.png") writes it to a file (.png, .svg or .pdf): a Matplotlib figure
