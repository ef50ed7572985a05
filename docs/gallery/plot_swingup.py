"""
Swing-up and capture by the LQR
===============================

The reference pendulum with both joints actuated and at most 10 N m per motor, swung up from
hanging to both rods upright: energy shaping pumps the energy ``E = T + Π`` to the upright
position's, then the LQR takes over inside its region of attraction and holds the top
(``skewpend.swingup`` and ``skewpend.views.figures.control_figure``).
"""

import math

import skewpend
from skewpend.views.figures import control_figure

params = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=math.radians(30), g=9.81)
run = skewpend.swingup(params, "up-up", "both", umax=10.0, t_end=6.0)
fig = control_figure(run)

# fig.savefig("figure.png") writes it to a file (.png, .svg or .pdf): a Matplotlib figure
