"""Where an SDF ``<uri>`` points, as Gazebo resolves it: ``model://``, ``package://``, ``file://``,
plain paths and Fuel's ``https://`` model URLs.

- ``model://name/rest``: ``name`` in the first resource path that has it (``GZ_SIM_RESOURCE_PATH``,
  ``IGN_GAZEBO_RESOURCE_PATH``, the world's ``models/``, ``worlds/models/``).
- ``package://pkg/rest``: the package's share directory, through the ament index.
- ``file:///abs/path``, ``/abs/path``, ``relative/path`` (to the file that names it). An absolute
  path that does not exist on this machine (a world copied from someone else's) whose folders
  name a model on the resource path resolves to that model, with a warning naming both.
- A world's URIs stay in the world's folder, the resource path, the Fuel cache and, for
  ``package://``, the package's share (symlinks followed), or in an installed package's share
  (``AMENT_PREFIX_PATH``, as written): a ``model://m/../../x``, an absolute path or a symlink
  elsewhere is refused, naming where it leads (:func:`resolve_uri`'s ``within``).
- ``https://fuel.gazebosim.org/1.0/<owner>/models/<name>[/<version>][/rest]``: the local Fuel
  cache (``GZ_FUEL_CACHE_PATH``, ``~/.gz/fuel``, ``~/.ignition/fuel``), newest version unless one
  is named. pppbot downloads nothing; a model missing from the cache is an error saying how to
  get it.
"""
from __future__ import annotations

import os
import urllib.parse
from collections.abc import Mapping, Sequence
from pathlib import Path

from pppbot_sim.errors import WorldError


class UriError(WorldError):
    """A URI that names nothing here; the message says what was looked at."""


def fuel_caches(environ: Mapping[str, str] | None = None) -> list[Path]:
    """Where Gazebo's Fuel tools keep downloaded models, in the order they are looked at."""
    environ = os.environ if environ is None else environ
    caches = [Path(environ[var]) for var in ("GZ_FUEL_CACHE_PATH", "IGN_FUEL_CACHE_PATH") if environ.get(var)]
    home = Path(environ.get("HOME") or Path.home())
    return [*caches, home / ".gz" / "fuel", home / ".ignition" / "fuel"]


def resolve_uri(uri: str, relative_to: Path, search: Sequence[Path], caches: Sequence[Path] = (),
                within: Sequence[Path] | None = None) -> tuple[Path, str | None]:
    """The path ``uri`` names (it may not exist: the caller checks what it needs) and a warning,
    or None. ``relative_to``: the directory of the file that holds the URI.

    ``within``: the folders a stranger's file (a world and the models it includes) may read
    from besides ``search``, ``caches`` and, for ``package://``, the package's share; the path,
    with its symlinks followed, must lie in one of them (None: anywhere, for a file the user
    names on the command line).

    Raises:
        UriError: a ``model://``, ``package://`` or Fuel URI that names nothing here, or a path
            outside what ``within`` allows.
    """
    uri = uri.strip()
    scheme, _, rest = uri.partition("://")
    if not _:
        scheme, rest = "", uri
    warning, share = None, None
    if scheme == "model":
        name, _, inner = rest.strip("/").partition("/")
        path = _model(name, search, uri) / inner
    elif scheme == "package":
        path, share = _package(rest, uri)
    elif scheme in ("http", "https"):
        path = _fuel(uri, caches)
    elif scheme in ("", "file"):
        path, warning = _path(Path(urllib.parse.unquote(rest)) if scheme == "file" else Path(rest), uri,
                              relative_to, search)
    else:
        raise UriError(f"{uri}: the scheme '{scheme}://' is not supported (model://, package://, file://, a path, "
                       "or a Fuel model URL)")
    if within is not None:
        check_inside(path, uri, [*within, *search, *caches, *([share] if share else [])])
    return path, warning


def check_inside(path: Path, uri: str, roots: Sequence[Path]) -> None:
    """Refuse ``path`` unless it is in an installed package's share (as written, without ``..``:
    a colcon ``--symlink-install`` links every file there to the sources) or, its symlinks
    followed, in one of ``roots``.

    Raises:
        UriError: neither.
    """
    written = Path(os.path.normpath(path.absolute()))
    # ".." after a symlink is the kernel's to resolve, not the text's: no share exception then.
    if ".." not in path.parts and any(written.is_relative_to(share) for share in installed_shares()):
        return
    real = path.resolve()
    if any(real.is_relative_to(root.resolve()) for root in roots):
        return
    looked = ", ".join(str(root) for root in roots)
    raise UriError(f"{uri}: {real} is outside the folders this world may read from ({looked}); copy it into the "
                   "world's folder or a model's, or add its folder to GZ_SIM_RESOURCE_PATH")


def installed_shares(environ: Mapping[str, str] | None = None) -> list[Path]:
    """The ``share`` folders of the ament prefixes (``AMENT_PREFIX_PATH``): what the user built
    and installed."""
    environ = os.environ if environ is None else environ
    prefixes = [Path(p) for p in environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    return [Path(os.path.normpath(prefix.absolute() / "share")) for prefix in prefixes]


def _path(path: Path, uri: str, relative_to: Path, search: Sequence[Path]) -> tuple[Path, str | None]:
    if not path.is_absolute():
        return relative_to / path, None
    moved = None if path.exists() else _model_on_resource_path(path, search)
    if moved is None:
        return path, None
    return moved, f"{uri} does not exist here; using {moved}, the model of that name on the resource path"


def _model(name: str, search: Sequence[Path], uri: str) -> Path:
    for base in search:
        if (base / name).is_dir():
            return base / name
    searched = ", ".join(str(p) for p in search) or "nothing"
    raise UriError(f"unknown model '{name}' ({uri}); searched {searched} (add its folder's parent to "
                   "GZ_SIM_RESOURCE_PATH)")


def _package(rest: str, uri: str) -> tuple[Path, Path]:
    package, _, inner = rest.partition("/")
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    except ImportError as exc:  # pragma: no cover - ament_index_python comes with rclpy
        raise UriError(f"{uri}: package:// needs ament_index_python") from exc
    try:
        share = Path(get_package_share_directory(package))
    except (PackageNotFoundError, ValueError) as exc:
        raise UriError(f"{uri}: package '{package}' is not in the ament index (AMENT_PREFIX_PATH); source its "
                       "workspace's setup.bash, or use model:// with GZ_SIM_RESOURCE_PATH") from exc
    return share / inner, share


def _model_on_resource_path(path: Path, search: Sequence[Path]) -> Path | None:
    """A missing absolute path's innermost folder that names a model on the resource path, with
    the rest of the path below it, when that exists."""
    parts = path.parts
    for index in range(len(parts) - 1, 0, -1):
        for base in search:
            candidate = base.joinpath(parts[index], *parts[index + 1:])
            if (base / parts[index]).is_dir() and candidate.exists():
                return candidate
    return None


def _fuel(uri: str, caches: Sequence[Path]) -> Path:
    parsed = urllib.parse.urlparse(uri)
    segments = [urllib.parse.unquote(s) for s in parsed.path.split("/") if s]
    if segments and segments[0] in ("1.0",):
        segments = segments[1:]
    if len(segments) < 3 or segments[1].lower() != "models":
        raise UriError(f"{uri}: not a Fuel model URL (https://fuel.gazebosim.org/1.0/<owner>/models/<name>)")
    owner, name, after = segments[0], segments[2], segments[3:]
    version = after[0] if after and after[0].isdigit() else None
    inner = after[1:] if version is not None else after
    if inner and inner[0] == "files":  # .../<version>/files/meshes/x.dae
        inner = inner[1:]
    for cache in caches:
        models = _child(cache / parsed.netloc, owner)
        model = _child(models / "models", name) if models is not None else None
        if model is None:
            continue
        versions = sorted((v for v in model.iterdir() if v.is_dir() and v.name.isdigit()), key=lambda v: int(v.name))
        if version is not None:
            chosen = next((v for v in versions if v.name == version), None)
        else:
            chosen = versions[-1] if versions else None
        if chosen is not None:
            return chosen.joinpath(*inner)
    looked = ", ".join(str(c) for c in caches) or "nothing"
    raise UriError(f"{uri}: the Fuel model '{owner}/{name}' is not in the local Fuel cache ({looked}); pppbot does "
                   f"not download. On a machine with Gazebo: gz fuel download -u '{uri}', then copy its cache "
                   "folder here (or the model's folder onto GZ_SIM_RESOURCE_PATH and use model://)")


def _child(directory: Path, name: str) -> Path | None:
    """``directory``'s entry named ``name``, ignoring case (Fuel's cache lowercases names)."""
    if not directory.is_dir():
        return None
    wanted = name.lower()
    return next((entry for entry in directory.iterdir() if entry.name.lower() == wanted and entry.is_dir()), None)
