"""Helpers of the simulator's tests."""
from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np
import pytest


def _placed_vertices(model: mujoco.MjModel, geom: str) -> np.ndarray:
    """A mesh geom's vertices where MuJoCo puts them in the world (after mj_forward)."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    gid = model.geom(geom).id
    mid = model.geom_dataid[gid]
    local = model.mesh_vert[model.mesh_vertadr[mid]:model.mesh_vertadr[mid] + model.mesh_vertnum[mid]]
    return np.asarray(local @ data.geom_xmat[gid].reshape(3, 3).T + data.geom_xpos[gid])


@pytest.fixture
def placed_vertices() -> Callable[[mujoco.MjModel, str], np.ndarray]:
    return _placed_vertices


@pytest.fixture(scope="session")
def opengl() -> None:
    """Skip a test that renders when this machine has no working OpenGL backend for MuJoCo (on Debian:
    libegl1 libegl-mesa0 libgl1-mesa-dri; .ci/run installs them). Probed once, in a child process."""
    import subprocess
    import sys

    probe = subprocess.run([sys.executable, "-c", "from pppbot_sim.render import create_gl_context; "
                                                  "create_gl_context(8, 8)"], capture_output=True, text=True,
                           timeout=120)
    if probe.returncode != 0:
        pytest.skip(f"no OpenGL backend: {probe.stderr.strip().splitlines()[-1] if probe.stderr.strip() else '?'}")
