"""
Chaos diagram
=============

Does skewing the hinges tame or feed chaos? The fraction of the energy surface whose largest
Lyapunov exponent is clearly positive, for skew angles from 0° to 90° and energies above rest
(``skewpend.chaos_diagram`` and ``skewpend.views.figures.chaos_diagram_figure``). A small
diagram: 4 angles × 6 energies × 16 starts over 60 s, so each fraction is uncertain by about
±0.1. Chaos sets in between 4 and 8 J, near the energy a flip needs (m2 g b ≈ 5.5 J).
"""

import numpy as np

import skewpend
from skewpend.views.figures import chaos_diagram_figure

params = skewpend.reference_parameters()
diagram = skewpend.chaos_diagram(params, alpha=np.radians([0.0, 30.0, 60.0, 90.0]),
                                 energy=[2.0, 4.0, 6.0, 8.0, 10.0, 12.0], samples=16, t_end=60.0)
fig = chaos_diagram_figure(diagram)

# fig.savefig("figure.png") writes it to a file (.png, .svg or .pdf): a Matplotlib figure
