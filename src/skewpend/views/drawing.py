"""Where the drawings put the links, for every view (the animation, the figures, the report and the browser views):
each link is drawn from its hinge to the next link's hinge, the last link from its hinge to its rod's end
(``(0, length, 0)`` in its body) -- or, where its centre of mass lies on the other side of the hinge (``com . j <
0``: a model read from MJCF whose zero is upright, the DeepMind acrobot), that rod mirrored through the hinge, to
where its body is (:func:`last_link_sign`).  So a chain whose next hinge sits anywhere on the parent -- the rotary pendulum's
pendulum on the hinge at the end of an arm that runs along its body's ``i`` -- is drawn as it is, and a chain
with every hinge at the end of the rod before is drawn as always (hinge ``i + 1`` is rod ``i``'s end).

Nothing here computes kinematics: the hinges' positions are the model's generated kinematics (the recursive
algorithms' graph, :func:`skewpend.numeric.recursive.hinge_positions`), the last rod's end the trajectory's own
``tips()`` (its compiled kernel's)."""

from __future__ import annotations

import numpy as np

__all__ = ["link_points", "last_link_sign", "drawn_reach", "drawn_depth", "drawn_frame"]


def link_points(model, y, tips) -> np.ndarray:
    """The drawn chain at the states ``y`` (rows; the first n columns, the angles, are read): shape (rows,
    n + 1, 3), world frame (j down) [m] -- the hinges ``o_1 ... o_n`` and the last rod's end, the last row of
    ``tips`` (the rods' ends, 3 n a row, the trajectory's ``tips()``).  Link ``i`` is drawn from point ``i``
    to point ``i + 1``."""
    from ..numeric.recursive import hinge_positions

    chain = model.as_chain()
    n = chain.n
    y = np.atleast_2d(np.asarray(y, dtype=float))
    tips = np.asarray(tips, dtype=float).reshape(-1, 3 * n)
    hinges = hinge_positions(chain, y[:, :n]).reshape(-1, n, 3)
    end = tips[:, None, 3 * (n - 1):]
    if last_link_sign(chain) < 0:  # the rod on its body's side of the hinge: the model's rod end mirrored there
        end = 2.0 * hinges[:, n - 1:] - end
    return np.concatenate([hinges, end], axis=1)


def last_link_sign(model) -> float:
    """Which way along its rod's line (its body's ``j``) the last link is drawn from its hinge: +1 towards the
    rod's end (``(0, length, 0)``, where a chain's rod runs), -1 the other way where the link's centre of mass
    lies there (``com . j < 0``: a model read from MJCF whose zero is upright, the DeepMind acrobot's lower arm
    -- its body runs up from the elbow at ``q = 0`` while a :class:`~skewpend.Link`'s rod runs along ``+j``),
    so the drawing shows the link where its mass is."""
    link = model.as_chain().links[-1]
    return -1.0 if float(link.com[1]) < 0.0 else 1.0


def drawn_reach(model) -> float:
    """The longest the drawn chain can be from the origin [m]: the hinges' offsets and the last rod's length
    (each link's drawn length; a chain hanging from hinge to rod's end: the sum of its rods' lengths)."""
    links = model.as_chain().links
    return float(sum(np.linalg.norm(np.asarray(link.offset, dtype=float)) for link in links) + links[-1].length)


def drawn_depth(model) -> float:
    """The deepest the drawn chain can reach below the roof [m]: :func:`drawn_reach`, but the first drawn link
    (hinge 1 to hinge 2, turning about hinge 1's fixed axis ``a``) reaches at most ``(v . a)(a . j) + |v - (v .
    a) a| sqrt(1 - (a . j)^2)`` down (``v`` its offset): a horizontal hinge's (the double pendulum's ``k``) all of
    ``|v|``, a vertical one's (a rotary pendulum's arm, turning in the horizontal plane) none of it."""
    links = model.as_chain().links
    norms = [float(np.linalg.norm(np.asarray(link.offset, dtype=float))) for link in links]
    norms[0] = float(links[0].offset[1])  # hinge 1 stays where it is: only its depth (negative above the roof)
    if len(links) > 1:
        a = np.asarray(links[0].axis, dtype=float)
        a = a / np.linalg.norm(a)
        v = np.asarray(links[1].offset, dtype=float)
        along = float(v @ a)
        across = float(np.sqrt(max(float(v @ v) - along * along, 0.0)))
        norms[1] = max(0.0, along * float(a[1]) + across * float(np.sqrt(max(1.0 - float(a[1]) ** 2, 0.0))))
    return max(0.0, float(sum(norms) + links[-1].length))


def drawn_frame(model):
    """Where a view looks when hinge 1 is not at the roof (a model read from MJCF: the DeepMind acrobot's shoulder
    2 m above its world's origin): ``(centre, radius)`` [m], the model's frame -- hinge 1 and a radius holding every
    place the drawn chain can reach from there (:func:`drawn_reach` less hinge 1's distance) and the roof; None
    where hinge 1 is at the roof (the views' framing of a chain hanging from it)."""
    links = model.as_chain().links
    o = np.asarray(links[0].offset, dtype=float)
    d = float(np.linalg.norm(o))
    if d == 0.0:
        return None
    return [float(v) for v in o], max(drawn_reach(model) - d, d)
