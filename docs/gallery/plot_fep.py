"""
Frequency-energy plot (backbones)
=================================

The nonlinear normal modes of the reference pendulum: the frequency of each family of periodic
orbits against its energy, from the linear modes (◀) up to the lowest energy at which a joint can
flip (``skewpend.backbones`` and ``skewpend.views.figures.fep_figure``). Solid: stable orbits;
dashed: unstable; circles: branch points (a Floquet multiplier through +1); the dotted line: the
3:2 internal resonance. Beside it, four of the orbits in the (φ, ψ) plane.
"""

import skewpend
from skewpend.views.figures import fep_figure

params = skewpend.reference_parameters()
bb = skewpend.backbones(params)
f1, f2 = bb.families
orbits = [(mode, E, fam.at_energy(E).trajectory()) for mode, fam in ((1, f1), (2, f2)) for E in (1.0, 5.0)]
fig = fep_figure(bb, orbits=orbits)

# fig.savefig("figure.png") writes it to a file (.png, .svg or .pdf): a Matplotlib figure
