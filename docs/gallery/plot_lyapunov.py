"""
Lyapunov spectrum
=================

The running estimates of the four Lyapunov exponents of the reference start over 1000 s
(``skewpend.lyapunov`` and ``skewpend.views.figures.lyapunov_figure``). They settle into pairs
±λ, as Hamiltonian mechanics demands: one positive exponent (chaos), two near zero and its
negative.
"""

import skewpend
from skewpend.views.figures import lyapunov_figure

params = skewpend.reference_parameters()
spec = skewpend.lyapunov(params, skewpend.reference_state(), t_end=1000.0)
fig = lyapunov_figure(spec)

# fig.savefig("figure.png") writes it to a file (.png, .svg or .pdf): a Matplotlib figure
