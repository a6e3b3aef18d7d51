"""A small recording stand-in for ``pychrono`` and ``pychrono.vehicle``.

PyChrono, Chrono's Python bindings, is distributed only through conda
(``conda install projectchrono::pychrono -c conda-forge``) and cannot be
installed here, so the modules terracone writes are run against this
stand-in.  It offers the names those modules use, with the calling
conventions of Chrono's own sources:

* ``src/chrono_vehicle/terrain/SCMTerrain.h``: ``SetSoilParameters`` takes
  eight numbers (Kphi, Kc, n, cohesion, friction, Janosi shear, elastic K,
  damping R); ``SoilParametersCallback::Set(loc, &Kphi, &Kc, &n, &coh,
  &mu_angle, &shear, &K, &R)`` writes through eight references, ``loc`` in
  the SCM frame; ``Initialize(sizeX, sizeY, delta)``.
* ``src/demos/python/vehicle/demo_VEH_DeformableSoil.py`` (Chrono 9): a
  Python callback subclasses ``veh.SoilParametersCallback``, calls its
  ``__init__``, reads ``loc.x``/``loc.y`` and writes each value with
  ``veh.doublep_assign(ptr, value)``; ``chrono.ChSystemSMC()``,
  ``SetCollisionSystemType(chrono.ChCollisionSystem.Type_BULLET)``,
  ``chrono.ChVector3d``, ``chrono.ChContactMaterialSMC()``, ``sys.Add(body)``,
  ``sys.DoStepDynamics(step)``; ``chrono.ChBodyEasyBox(x, y, z, density,
  visualize, collide, material)``.

Every call is recorded in :data:`CALLS` as (name, args).
"""

from __future__ import annotations

import sys
import types

CALLS: list[tuple[str, tuple]] = []


class Vector:
    """``ChVector3d``: x, y, z attributes."""

    def __init__(self, x=0.0, y=0.0, z=0.0):
        self.x, self.y, self.z = float(x), float(y), float(z)


class DoublePtr:
    """What Chrono passes for a ``double&`` (SWIG's ``double *``)."""

    def __init__(self, value: float = float("nan")):
        self.value = value


def doublep_assign(ptr: DoublePtr, value: float) -> None:
    if not isinstance(ptr, DoublePtr):
        raise TypeError("doublep_assign needs a double pointer")
    ptr.value = float(value)


class SoilParametersCallback:
    """Abstract base: a subclass must call ``__init__`` and define ``Set``."""

    def __init__(self):
        self.base_initialised = True

    def Set(self, loc, *ptrs):  # pragma: no cover - the subclass's job
        raise NotImplementedError


class SCMTerrain:
    """Records the soil it is given; ``soil_at`` calls the callback as Chrono does."""

    def __init__(self, system, visualization_mesh=True):
        CALLS.append(("SCMTerrain", (system,)))
        self.system = system
        self.params = None
        self.callback = None

    def SetSoilParameters(self, *args):
        if len(args) != 8 or not all(isinstance(a, float) for a in args):
            raise TypeError(f"SetSoilParameters takes 8 numbers (got {args!r})")
        CALLS.append(("SetSoilParameters", args))
        self.params = args

    def RegisterSoilParametersCallback(self, cb):
        if not isinstance(cb, SoilParametersCallback) or not getattr(cb, "base_initialised", 0):
            raise TypeError("expected an initialised SoilParametersCallback")
        CALLS.append(("RegisterSoilParametersCallback", (cb,)))
        self.callback = cb

    def Initialize(self, size_x, size_y, delta):
        CALLS.append(("Initialize", (size_x, size_y, delta)))

    def soil_at(self, x: float, y: float) -> tuple[float, ...]:
        """The eight values the callback writes at (x, y) of the SCM frame."""
        ptrs = [DoublePtr() for _ in range(8)]
        self.callback.Set(Vector(x, y, 0.0), *ptrs)
        return tuple(p.value for p in ptrs)


class ChSystemSMC:
    def __init__(self):
        self.bodies, self.steps = [], 0

    def SetCollisionSystemType(self, kind):
        CALLS.append(("SetCollisionSystemType", (kind,)))

    def SetGravitationalAcceleration(self, g):
        CALLS.append(("SetGravitationalAcceleration", (g.x, g.y, g.z)))

    def Add(self, body):
        self.bodies.append(body)

    def DoStepDynamics(self, step):
        self.steps += 1


class ChBodyEasyBox:
    def __init__(self, x, y, z, density, visualize, collide, material):
        CALLS.append(("ChBodyEasyBox", (x, y, z, density, visualize, collide)))
        self.pos = Vector()

    def SetPos(self, v):
        self.pos = v

    def GetPos(self):
        return self.pos


def install(monkeypatch) -> None:
    """Put the stand-in in ``sys.modules`` for one test (``monkeypatch`` undoes it)."""
    CALLS.clear()
    chrono = types.ModuleType("pychrono")
    vehicle = types.ModuleType("pychrono.vehicle")
    chrono.ChVector3d = Vector
    chrono.ChSystemSMC = ChSystemSMC
    chrono.ChCollisionSystem = types.SimpleNamespace(Type_BULLET="BULLET")
    chrono.ChContactMaterialSMC = lambda: "material"
    chrono.ChBodyEasyBox = ChBodyEasyBox
    chrono.vehicle = vehicle
    vehicle.SCMTerrain = SCMTerrain
    vehicle.SoilParametersCallback = SoilParametersCallback
    vehicle.doublep_assign = doublep_assign
    monkeypatch.setitem(sys.modules, "pychrono", chrono)
    monkeypatch.setitem(sys.modules, "pychrono.vehicle", vehicle)
