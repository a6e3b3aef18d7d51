"""One name per concept: the parameter vocabulary of terracone.

Every terrain parameter has one name in the Python API beside the JSON keys,
CLI flags and terrain-library keys that earlier releases fixed (contracts).
:data:`NAMES` is that table; ``docs/physics.md`` shows it with the naming rules.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Nomenclature, eqs. (2-2) to (2-7).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Name", "NAMES", "markdown_table"]


@dataclass(frozen=True)
class Name:
    """How one concept is called in the paper, the Python API, JSON and the CLI.

    Attributes
    ----------
    concept : str
    symbol : str
        Symbol in the paper's nomenclature ([1]_ of the module).
    python : str
        The Python name (keyword argument and attribute).
    json : str
        Key in JSON results and calibration files ("" for none).
    cli : str
        Command-line flag or ``--bounds`` key ("" for none).
    library : str
        Key of a terrain-library record (SI; "" for none).
    unit : str
        SI unit (US customary in parentheses where the CLI offers it).
    """

    concept: str
    symbol: str
    python: str
    json: str
    cli: str
    library: str
    unit: str


#: The vocabulary (see ``docs/physics.md``): concept | symbol | python | json | cli | library | unit.
_TABLE = """
Bekker cohesive modulus | k_c | kc | kc | --kc; --bounds kc=LO:HI | kc | kN/m^(n+1) (lb/in^(n+1))
Bekker frictional modulus | k_phi | kphi | kphi | --kphi; --bounds kphi=LO:HI | kphi | kN/m^(n+2) (lb/in^(n+2))
sinkage exponent | n | n | n | --n; --bounds n=LO:HI | n | -
cone (metal)-terrain adhesion | c_c | cc | cc | --cc; --bounds cc=LO:HI | cc | kPa (psi)
cone (metal)-terrain friction angle | phi_c | phic_deg | phic_deg | --phic; --bounds phic=LO:HI | phic_deg | deg
cone (metal)-terrain shear deformation parameter | K_c | K_cone | Kc | --Kc; --bounds Kc=LO:HI | Kc | m (in)
terrain cohesion | c | c | c | --cohesion | c_kpa | kPa (psi)
terrain internal friction angle | phi | phi_deg | phi_deg |  | phi_deg | deg
terrain shear deformation modulus | K | K | K | --janosi | K_m | m (in)
ratio kc/kphi held from a calibration | k_c/k_phi | kc_over_kphi |  |  |  | m
pressure law | RM0, RM1 | model | model | --model | model | -
RM1 transition radius | r_min | r_min | r_min | --r-min | r_min | m (in)
"""
NAMES: tuple[Name, ...] = tuple(
    Name(*(cell.strip() for cell in line.split("|"))) for line in _TABLE.strip().splitlines()
)


def markdown_table() -> str:
    """:data:`NAMES` as the Markdown table of ``docs/physics.md``."""

    def code(x: str) -> str:
        return f"`{x}`" if x else "-"

    rows = [
        "| concept | paper | Python | JSON key | CLI | library key | unit |",
        "|---|---|---|---|---|---|---|",
    ]
    for nm in NAMES:
        cli = "; ".join(code(p.strip()) for p in nm.cli.split(";")) if nm.cli else "-"
        rows.append(
            f"| {nm.concept} | {nm.symbol} | {code(nm.python)} | {code(nm.json)} "
            f"| {cli} | {code(nm.library)} | {nm.unit} |"
        )
    return "\n".join(rows)
