"""
A frame of the 3D animation
===========================

One still frame of the video that ``skewpend animate`` makes (``skewpend.views.animation``):
both rods as shaded solids, the roof's hinge axis and the second hinge axis ``e = P1 · e0``
(turning with rod 1) as arrows with the skew angle α between them, the fading trail of rod 2's
tip, and a readout of time, angles and energy. Here the reference case 3 s after its release.
The renderer draws frame ``k`` of a trajectory sampled at the video's frame times; its pixels
are shown as an image.
"""

import matplotlib.pyplot as plt

import skewpend
from skewpend.views.animation import FrameRenderer

fps = 30
params = skewpend.reference_parameters()
tr = skewpend.simulate(params, skewpend.reference_state(), 3.0, dt_out=1.0 / fps)

renderer = FrameRenderer(tr, size=(640, 480))
renderer.draw(len(tr.t) - 1)  # the last frame: t = 3 s
pixels = renderer.rgb()
renderer.close()

height, width, _ = pixels.shape
fig = plt.figure(figsize=(width / 100, height / 100), dpi=100)
ax = fig.add_axes((0, 0, 1, 1))
ax.imshow(pixels)
ax.set_axis_off()
# plt.show() opens it in a window
