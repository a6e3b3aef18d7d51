"""terracone: Bekker-Wong terrain parameters from cone penetrometer data.

The method is that of Huang, Wong, Preston-Thomas and Jayakumar, "Predicting
terrain parameters for physics-based vehicle mobility models from cone index
data".  Forward models live in :mod:`terracone.physics.cone` and
:mod:`terracone.physics.plate`, the inversion in :mod:`terracone.inverse`.
"""

from importlib.metadata import PackageNotFoundError, version

from terracone.data import (
    CIProfile,
    InputError,
    PlateTest,
    ProfileSet,
    ShearTest,
    TerrainParameters,
    TerrainShear,
)
from terracone.physics.cone import CONES, Cone, cone_index, get_cone
from terracone.physics.metrics import agreement
from terracone.physics.plate import plate_pressure

try:
    __version__ = version("terracone")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0+unknown"

__all__ = [
    "CONES",
    "CIProfile",
    "Cone",
    "InputError",
    "PlateTest",
    "ProfileSet",
    "ShearTest",
    "TerrainParameters",
    "TerrainShear",
    "agreement",
    "cone_index",
    "get_cone",
    "plate_pressure",
    "__version__",
]
