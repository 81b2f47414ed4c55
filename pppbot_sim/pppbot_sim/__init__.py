"""MuJoCo simulator node for ppp_bot: Gazebo-style SDF worlds, spawning, lidar, IMU, cameras, clock,
ground-truth maps.

MuJoCo loads the OpenGL backend ``MUJOCO_GL`` names when it is imported, and fails to import at
all when that backend is unknown or its library is missing (``MUJOCO_GL=osmesa`` without
libOSMesa). Only the cameras need OpenGL: so MuJoCo is imported here first, and if its backend
breaks the import, it is imported again without one and the cameras say why they are off
(:mod:`pppbot_sim.render`); physics, lidar and everything else run.
"""
import os as _os
import sys as _sys

try:
    import mujoco as _mujoco  # noqa: F401 - imported for its side effect: the backend check
except Exception as _exc:  # MuJoCo raises RuntimeError for an unknown value, anything for a broken library
    for _name in [m for m in _sys.modules if m.split(".")[0] in ("mujoco", "OpenGL")]:
        del _sys.modules[_name]
    _os.environ["PPPBOT_REFUSED_MUJOCO_GL"] = (f"MUJOCO_GL={_os.environ.get('MUJOCO_GL', '')!r} stops MuJoCo "
                                               f"from loading ({type(_exc).__name__}: {_exc})")
    _os.environ["MUJOCO_GL"] = "disable"
    import mujoco as _mujoco  # noqa: F401
