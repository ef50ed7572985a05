"""skewpend: the double pendulum with skewed hinge axes."""
__version__ = "0.1.0"
from .model import Parameters
from .errors import SkewpendError, ParameterError, NotNumericError, EquilibriumError
def __getattr__(name):
    if name in ("derive", "EquationsOfMotion", "LinearEquations"):
        from . import derive as _d
        return getattr(_d, name)
    raise AttributeError(name)
