"""``equilibria``: every equilibrium of the model, with its stability and linearisation."""

from __future__ import annotations

import sys
from enum import Enum
from typing import Annotated

import typer

from .options import CONFIG, MODEL, command, resolve

COMMANDS = ("equilibria",)


class EquilibriaFormat(str, Enum):
    text = "text"
    json = "json"


@command(MODEL)
def equilibria(
    model: dict,
    fmt: Annotated[EquilibriaFormat, typer.Option("--format", "-f", help="text (a table) or json")] = EquilibriaFormat.text,
    config: CONFIG = None,
) -> None:
    """Every equilibrium on the torus (constant torques allowed): its energy, stability, Morse index, frequencies and growth rates.

    From a --config run file it takes [parameters].
    """
    from ..analysis.equilibria import equilibria as find

    params = resolve("equilibria", config, parameters=model).parameters()
    result = find(params)
    if fmt is EquilibriaFormat.json:
        import json

        from ..results import plain

        data = {
            "equilibria": [
                {"label": e.label, "phi": e.q[0], "psi": e.q[1], "potential": e.potential, "morse_index": e.morse_index,
                 "stable": e.stable, "frequencies": e.frequencies, "growth_rates": e.growth_rates,
                 "unstable_directions": e.unstable_directions.T, "eigenvalues": [[z.real, z.imag] for z in e.eigenvalues],
                 "M": e.M, "C": e.C, "K": e.K}
                for e in result
            ],
            "index_sum": result.index_sum,
            "status": result.status.name,
            "message": result.message,
        }
        sys.stdout.write(json.dumps(plain(data), indent=2, allow_nan=False) + "\n")
    else:
        sys.stdout.write(result.table() + "\n" + result.message + "\n")
    return result
