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

The stand-in moves what lies on the terrain, so that a script's printed sinkage
means something: after each ``DoStepDynamics`` every colliding box of the system
rests where SCM's normal pressure carries its weight (quasi-static, no
dynamics).  SCM's pressure is Bekker's ``sigma = (Kc / b + Kphi) z^n`` on the
total sinkage z, with ``1/b = perimeter / (2 area)`` of the contact patch
(``src/chrono_vehicle/terrain/SCMTerrain.cpp``: ``p.oob = p.perimeter / (2 *
p.area)`` and ``nr.sigma = (contact_patches[patch_id].oob * Bekker_Kc +
Bekker_Kphi) * pow(nr.sinkage, Bekker_n)``; the elastic and damping terms
vanish at rest), and the force on each grid node the box covers is
``m_area * sigma`` with ``m_area`` the grid step squared, 1/b that of the
convex hull of those nodes.  So a box of mass m under gravity g, covering N
nodes of a grid of step d whose hull is hx by hy, sinks to
``z = (m |g_z| / (N d^2) / (Kc (hx + hy) / (hx hy) + Kphi)) ** (1 / n)``, with
the soil values the terrain was given (those of the callback at the box's
centre), in SCM's default frame (the plane z = 0, z up).  Gravity starts at
Chrono's default (0, -9.8, 0) (``ChSystem::ChSystem``), which loads nothing
along z: a script must set it.

Every call is recorded in :data:`CALLS` as (name, args).
"""

from __future__ import annotations

import math
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
        self.delta = None  # the grid step of Initialize
        if isinstance(system, ChSystemSMC):  # Chrono adds the terrain to the system
            system.terrains.append(self)

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
        self.delta = float(delta)

    def soil_at(self, x: float, y: float) -> tuple[float, ...]:
        """The eight values the callback writes at (x, y) of the SCM frame."""
        ptrs = [DoublePtr() for _ in range(8)]
        self.callback.Set(Vector(x, y, 0.0), *ptrs)
        return tuple(p.value for p in ptrs)

    def sinkage(self, body: ChBodyEasyBox, g_z: float) -> float:
        """Where SCM's Bekker pressure carries ``body`` [m below the plane z = 0]."""
        soil = self.params if self.callback is None else self.soil_at(body.pos.x, body.pos.y)
        if soil is None:
            raise RuntimeError("SCMTerrain has no soil: SetSoilParameters or a callback first")
        kphi, kc, n = soil[:3]
        if self.delta is None:
            raise RuntimeError("SCMTerrain has no grid: Initialize(size_x, size_y, delta) first")
        d = self.delta
        # the grid nodes whose vertical ray meets the box's footprint
        xs = [i * d for i in range(-1000, 1001) if abs(i * d - body.pos.x) < body.size[0] / 2]
        ys = [j * d for j in range(-1000, 1001) if abs(j * d - body.pos.y) < body.size[1] / 2]
        if not xs or not ys:
            return 0.0
        hull_x, hull_y = xs[-1] - xs[0], ys[-1] - ys[0]  # the nodes' convex hull: a rectangle
        area, perimeter = hull_x * hull_y, 2.0 * (hull_x + hull_y)
        oob = perimeter / (2.0 * area) if area >= 1e-6 else 0.0
        # each node carries sigma on d^2: the weight spread over len(xs) len(ys) d^2
        sigma = body.mass * max(0.0, -g_z) / (len(xs) * len(ys) * d * d)  # [Pa]
        return (sigma / (kc * oob + kphi)) ** (1.0 / n)


class ChSystemSMC:
    def __init__(self):
        self.bodies, self.terrains, self.steps, self.time = [], [], 0, 0.0
        self.gravity = (0.0, -9.8, 0.0)  # Chrono's default (y up)

    def SetCollisionSystemType(self, kind):
        CALLS.append(("SetCollisionSystemType", (kind,)))

    def SetGravitationalAcceleration(self, g):
        CALLS.append(("SetGravitationalAcceleration", (g.x, g.y, g.z)))
        self.gravity = (g.x, g.y, g.z)

    def Add(self, body):
        self.bodies.append(body)

    def DoStepDynamics(self, step):
        """One step: each colliding box comes to rest on the terrain (see the module)."""
        if not step > 0:
            raise ValueError(f"step must be > 0 (got {step!r})")
        self.steps += 1
        self.time += step
        for terrain in self.terrains:
            for body in self.bodies:
                if isinstance(body, ChBodyEasyBox) and body.collide:
                    z = terrain.sinkage(body, self.gravity[2])
                    body.pos = Vector(body.pos.x, body.pos.y, body.size[2] / 2.0 - z)


class ChBodyEasyBox:
    """A box of sides x, y, z [m] and mass density * x * y * z [kg], centred at ``pos``."""

    def __init__(self, x, y, z, density, visualize, collide, material):
        CALLS.append(("ChBodyEasyBox", (x, y, z, density, visualize, collide)))
        if not all(math.isfinite(v) and v > 0 for v in (x, y, z, density)):
            raise ValueError(f"ChBodyEasyBox needs sizes and density > 0 (got {x, y, z, density})")
        self.size = (float(x), float(y), float(z))
        self.mass = float(density) * x * y * z
        self.collide = bool(collide)
        self.pos = Vector()

    def SetPos(self, v):
        self.pos = v

    def GetPos(self):
        return self.pos


def modules() -> tuple[types.ModuleType, types.ModuleType]:
    """New ``pychrono`` and ``pychrono.vehicle`` stand-in modules (empties :data:`CALLS`)."""
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
    return chrono, vehicle


def install(monkeypatch) -> None:
    """Put the stand-in in ``sys.modules`` for one test (``monkeypatch`` undoes it)."""
    chrono, vehicle = modules()
    monkeypatch.setitem(sys.modules, "pychrono", chrono)
    monkeypatch.setitem(sys.modules, "pychrono.vehicle", vehicle)
