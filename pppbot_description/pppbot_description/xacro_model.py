"""Expand ppp_bot's xacro (or any xacro) into a URDF string, with errors that point at the file.

Example::

    urdf = process_xacro(mappings={"samples": "360", "use_camera": "false"})
"""
from __future__ import annotations

import re
import xml.parsers.expat
from collections.abc import Mapping
from pathlib import Path

import xacro

from pppbot_common.resources import share_directory
from pppbot_common.xml_files import XmlFileError, refuse_entities
from pppbot_description.errors import DescriptionError

PACKAGE = "pppbot_description"
ROBOT_XACRO = "robot.urdf.xacro"
_ARG_DECLARATION = re.compile(r"<xacro:arg\s+name\s*=\s*[\"']([^\"']+)[\"']")


def urdf_directory() -> Path:
    """``share/pppbot_description/urdf`` when installed, else the source folder."""
    return share_directory(PACKAGE, "urdf", Path(__file__).resolve().parent.parent / "urdf")


def default_xacro_path() -> Path:
    """ppp_bot's top-level xacro file."""
    return urdf_directory() / ROBOT_XACRO


def declared_arguments(files: list[Path]) -> set[str]:
    """Names of the ``<xacro:arg>`` declarations in ``files``."""
    names: set[str] = set()
    for path in files:
        if path.is_file():
            names.update(_ARG_DECLARATION.findall(path.read_text(errors="replace")))
    return names


def _line_of(path: Path, needle: str) -> int | None:
    try:
        for number, line in enumerate(path.read_text(errors="replace").splitlines(), start=1):
            if needle in line:
                return number
    except OSError:
        return None
    return None


def _locate_error(exc: BaseException, top: Path) -> str:
    """``file:line: message`` for an xacro or XML error, as precise as xacro allows."""
    stack = [Path(p) for p in getattr(xacro, "filestack", []) if p]
    current = stack[-1] if stack else top
    if isinstance(exc, xml.parsers.expat.ExpatError):
        return f"{current}:{exc.lineno}: malformed XML: {xml.parsers.expat.ErrorString(exc.code)}"
    if isinstance(exc, UnicodeDecodeError):
        return f"{current}: not a text file: byte {exc.start} is not {exc.encoding} ({exc.reason})"
    message = str(exc).strip().replace("\n", " ")
    missing = re.search(r"No such file or directory: (\S+)", message)
    if missing:
        missing_path = Path(missing.group(1))
        if missing_path == top:
            return f"{top}: file not found"
        line = _line_of(current, missing_path.name)
        where = f"{current}:{line}" if line else str(current)
        return f"{where}: included file not found: {missing_path}"
    undefined = re.search(r"name '(\w+)' is not defined", message)
    line = _line_of(current, undefined.group(1)) if undefined else None
    return f"{current}:{line}: {message}" if line else f"{current}: {message}"


def process_xacro(path: str | Path | None = None, mappings: Mapping[str, str] | None = None) -> str:
    """Expand a xacro file into URDF XML.

    Args:
        path: the xacro file; ppp_bot's ``robot.urdf.xacro`` when None.
        mappings: xacro arguments (``name`` → value as text).

    Raises:
        DescriptionError: missing file or include, malformed XML, a xacro error, or
            a mapping that names no ``<xacro:arg>``; the message says file and line.
    """
    top = Path(path) if path is not None else default_xacro_path()
    args = {str(k): str(v) for k, v in (mappings or {}).items()}
    try:
        earlier = len(xacro.all_includes)  # xacro appends every include it reads, and never forgets
        document = xacro.process_file(str(top), mappings=args)
        included = [top, *dict.fromkeys(Path(p) for p in xacro.all_includes[earlier:])]
        for file in included:  # expat fetched nothing and expanded nothing beyond its limits; still refused
            refuse_entities(file.read_bytes(), str(file))
    except XmlFileError as exc:
        raise DescriptionError(str(exc)) from exc
    except (xacro.XacroException, xml.parsers.expat.ExpatError, OSError, UnicodeDecodeError,
            RuntimeError) as exc:  # xacro's checks of attributes raise RuntimeError
        raise DescriptionError(_locate_error(exc, top)) from exc
    unknown = sorted(set(args) - declared_arguments(included))
    if unknown:
        known = ", ".join(sorted(declared_arguments(included))) or "none"
        raise DescriptionError(f"{top}: unknown xacro argument(s) {', '.join(unknown)} (declared: {known})")
    return str(document.toprettyxml(indent="  "))


def read_robot_description(value: str) -> tuple[str, str]:
    """``(urdf_xml, source)`` from a ``robot_description`` value as pppbot nodes take it:
    URDF XML itself, the path of a ``.urdf`` or ``.xacro`` file, or empty for ppp_bot.

    Raises:
        DescriptionError: unreadable file or a xacro error.
    """
    text = value.strip()
    if text.startswith("<"):
        return text, "the robot_description parameter"
    path = Path(text).expanduser() if text else default_xacro_path()
    if path.suffix == ".xacro":
        return process_xacro(path), str(path)
    try:
        return path.read_text(), str(path)
    except OSError as exc:
        raise DescriptionError(f"robot_description: cannot read '{path}': {exc.strerror}") from exc
