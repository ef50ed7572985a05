"""The symbolic layer: parameters, rotation-tensor kinematics, the derivation by Lagrange's
equations, and its renderers. The only layer that imports SymPy at module level."""
