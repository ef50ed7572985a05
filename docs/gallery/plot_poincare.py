"""
Poincaré section
================

Where orbits of energy 6 J cross the section φ = 0 (moving forwards), in the canonical
coordinates (ψ, p_ψ), one colour per orbit (``skewpend.poincare`` and
``skewpend.views.figures.poincare_figure``). At this energy, just above the m2 g b ≈ 5.5 J a flip
needs, phase space is mixed: orbits started in the islands draw closed curves (regular,
quasi-periodic motion), those started in the sea between them scatter their crossings over it
(chaos).
"""

import skewpend
from skewpend.views.figures import poincare_figure

params = skewpend.reference_parameters()
# starts (psi, p_psi) on the section: four in the islands, the others in the chaotic sea
seeds = [(0.0, 0.95), (0.0, 1.1), (1.5, -0.6), (3.0, 0.25),
         (0.0, -0.35), (0.9, -0.6), (1.0, 0.0), (-1.5, 0.5), (2.0, -0.5), (-0.5, -1.0)]
sec = skewpend.poincare(params, 6.0, section="phi=0", direction=+1, seeds=seeds, n_orbits=len(seeds),
                        n_crossings=400)
fig = poincare_figure(sec)

# fig.savefig("figure.png") writes it to a file (.png, .svg or .pdf): a Matplotlib figure
