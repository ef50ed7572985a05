"""Architecture: the numeric layer runs without SymPy once the generated kernel is cached,
and ``skewpend --help`` imports neither SymPy nor NumPy."""

from __future__ import annotations

import subprocess
import sys

from skewpend import Parameters, simulate

SCRIPT = """
import sys
from skewpend import Parameters, simulate
tr = simulate(Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81), (1.2, -0.8, 0, 0), 1.0)
assert tr.success
print("sympy" in sys.modules)
"""


def test_simulation_does_not_import_sympy_on_a_cache_hit():
    simulate(Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81), (1.2, -0.8, 0, 0), 0.1)  # warm the cache
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


def test_help_is_light():
    code = (
        "import sys\nfrom skewpend.cli import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        "print('sympy' in sys.modules, 'numpy' in sys.modules, 'skewpend.compiled' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "False False False"
