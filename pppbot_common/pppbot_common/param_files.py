"""YAML files a user brings, checked before anything reads them: ROS 2 parameter files (``--params-file``,
a launch's ``parameters=[...]``) and, through :func:`load_yaml_file`, any other YAML file.

Each problem is one message naming the file, where in it (``line L, column C``, 1-based, when the
problem has a place) and what is allowed. A parameter file's shape is rcl's
(``rcl_yaml_param_parser``, the parser every ROS 2 node uses), and what it refuses is refused here
in the same places, with the first bad key named::

    /**:                        # every node; also /*, /ns/node, /ns/*/node
      ros__parameters:
        use_sim_time: true
    amcl:                       # a node name: letters, digits and _, not starting with a digit
      ros__parameters:
        alpha1: 0.2             # a scalar, or a list of scalars of one type
        laser:
          max_beams: 60         # nested names are dotted: laser.max_beams
    ns:                         # namespaces may also nest as keys: ns/map_server
      map_server:
        ros__parameters: {}

Stricter than rcl in two places, both mistakes rcl lets through silently: a document that is not
a mapping (rcl ignores a lone scalar) and a list holding lists or mappings (no parameter type can
hold one).
"""
from __future__ import annotations

import re
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import yaml

from pppbot_common.errors import ParameterFileError, PppbotError

#: The key under a node name that holds its parameters.
PARAMS_KEY = "ros__parameters"
#: One token of a node name or namespace (rcl's rule), or a wildcard.
_NAME_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*|\*\*?")

_STR = "tag:yaml.org,2002:str"
_NULL = "tag:yaml.org,2002:null"
#: Scalar tags by the parameter type they give; any other tag (a date, ``!!binary``) is a string to rcl.
_TYPES = {"tag:yaml.org,2002:bool": "bool", "tag:yaml.org,2002:int": "integer",
          "tag:yaml.org,2002:float": "double"}


def _position(text: str | bytes, offset: int) -> tuple[int, int]:
    """1-based (line, column) of ``offset`` in ``text``."""
    newline = "\n" if isinstance(text, str) else b"\n"
    line = text.count(newline, 0, offset) + 1  # type: ignore[arg-type]
    return line, offset - (text.rfind(newline, 0, offset) + 1) + 1  # type: ignore[arg-type]


def read_yaml_text(path: Path) -> tuple[str, str | None, int | None, int | None]:
    """The text of a YAML file (UTF-8, a byte-order mark dropped), or why it has none: returns
    ``(text, problem, line, column)`` with ``problem`` None when the text was read."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        return "", f"cannot read the file ({exc.strerror or exc})", None, None
    try:
        return data.decode("utf-8-sig"), None, None, None
    except UnicodeDecodeError as exc:
        line, column = _position(data, exc.start)
        return "", f"not a text file: byte 0x{data[exc.start]:02x} is not UTF-8 (a YAML file is UTF-8 text)", \
            line, column


def describe_yaml_error(exc: yaml.YAMLError, text: str) -> tuple[str, int | None, int | None]:
    """What a PyYAML error says, and its 1-based line and column when it has them."""
    if isinstance(exc, yaml.reader.ReaderError):
        line, column = _position(text, exc.position)
        return f"not valid YAML: character {exc.character!r} is not allowed in a YAML file", line, column
    if isinstance(exc, yaml.MarkedYAMLError):
        what = exc.problem or exc.context or "syntax error"
        mark, started = exc.problem_mark or exc.context_mark, exc.context_mark
        if exc.problem and exc.context and started is not None:
            thing = exc.context.removeprefix("while parsing ").removeprefix("while scanning ")
            what = f"{what} (in {thing} from line {started.line + 1}, column {started.column + 1})"
        if mark is not None:
            return f"not valid YAML: {what}", mark.line + 1, mark.column + 1
        return f"not valid YAML: {what}", None, None
    return f"not valid YAML: {exc}", None, None


def load_yaml_file(path: str | Path, error: type[PppbotError]) -> Any:
    """The one YAML document in ``path`` (None when the file holds none).

    Raises:
        error: "``<path>: line L, column C: <what>``" for a file that cannot be read, is not
            UTF-8 text, is not valid YAML or holds more than one document.
    """
    path = Path(path)
    text, problem, line, column = read_yaml_text(path)
    if problem is None:
        try:
            return yaml.safe_load(text)
        except yaml.YAMLError as exc:
            problem, line, column = describe_yaml_error(exc, text)
    where = f"line {line}, column {column}: " if line is not None else ""
    raise error(f"{path}: {where}{problem}")


def check_parameter_file(path: str | Path) -> dict[str, dict[str, Any]]:
    """Check a ROS 2 parameter file as rcl reads it; its parameters by node name.

    Returns:
        ``{node name: {parameter: value}}``: names as written, nested namespace keys joined
        with ``/`` (``ns/map_server``, ``/**``); nested parameter mappings stay nested. Several
        YAML documents are merged in order, later values winning.

    Raises:
        ParameterFileError: "``<path>: line L, column C: <what>``" naming the first problem:
            unreadable, not UTF-8, not valid YAML, or not of the shape
            ``<node name>: ros__parameters: {<name>: <value>}`` (naming the key).
    """
    path = Path(path)
    text, problem, line, column = read_yaml_text(path)
    if problem is not None:
        raise ParameterFileError(path, problem, line, column)
    try:
        loader = yaml.SafeLoader(text)  # refuses unprintable characters at once
    except yaml.YAMLError as exc:
        what, line, column = describe_yaml_error(exc, text)
        raise ParameterFileError(path, what, line, column) from None
    try:
        nodes: dict[str, dict[str, Any]] = {}
        while loader.check_node():
            document = loader.get_node()
            if document is None:
                continue
            for name, params in _check_document(path, loader, document):
                nodes.setdefault(name, {}).update(loader.construct_object(params, deep=True))
        return nodes
    except yaml.YAMLError as exc:
        what, line, column = describe_yaml_error(exc, text)
        raise ParameterFileError(path, what, line, column) from None
    finally:
        loader.dispose()


def _fail(path: Path, node: yaml.Node, what: str) -> ParameterFileError:
    return ParameterFileError(path, what, node.start_mark.line + 1, node.start_mark.column + 1)


def _kind(node: yaml.Node) -> str:
    if isinstance(node, yaml.MappingNode):
        return "a mapping"
    if isinstance(node, yaml.SequenceNode):
        return "a list"
    return "nothing" if node.tag == _NULL else f"the value {node.value!r}"


def _items(loader: yaml.SafeLoader, node: yaml.MappingNode) -> list[tuple[yaml.Node, yaml.Node]]:
    loader.flatten_mapping(node)  # YAML merge keys (<<) become ordinary entries
    return list(node.value)


def _check_document(path: Path, loader: yaml.SafeLoader, document: yaml.Node) -> Iterator[tuple[str, yaml.Node]]:
    """Each node name of a document with its ``ros__parameters`` mapping (checked)."""
    if isinstance(document, yaml.ScalarNode) and document.tag == _NULL:
        return
    if not isinstance(document, yaml.MappingNode):
        raise _fail(path, document, f"a parameter file is a mapping of node names to 'ros__parameters:', "
                                    f"not {_kind(document)}")
    yield from _check_names(path, loader, document, "", set(), (id(document),))


def _check_names(path: Path, loader: yaml.SafeLoader, mapping: yaml.MappingNode, prefix: str,
                 seen: set[int], chain: tuple[int, ...]) -> Iterator[tuple[str, yaml.Node]]:
    """The node names under ``mapping`` (``seen``: parameter mappings checked already; ``chain``:
    the namespace mappings around this one)."""
    for key, value in _items(loader, mapping):
        name = _name_key(path, key, prefix)
        if isinstance(value, yaml.MappingNode):
            entries = _items(loader, value)
            keys = [k for k, _ in entries]
            if any(isinstance(k, yaml.ScalarNode) and k.value == PARAMS_KEY for k in keys):
                other = next((k for k in keys if not (isinstance(k, yaml.ScalarNode) and k.value == PARAMS_KEY)),
                             None)
                if other is not None:
                    raise _fail(path, other, f"key '{name}/{getattr(other, 'value', other)}': a node name holds "
                                             f"only '{PARAMS_KEY}:'")
                params = next(v for k, v in entries if isinstance(k, yaml.ScalarNode) and k.value == PARAMS_KEY)
                if not isinstance(params, yaml.MappingNode):
                    raise _fail(path, params, f"key '{name}/{PARAMS_KEY}' must be a mapping of parameter names "
                                              f"to values (use {{}} for none), not {_kind(params)}")
                _check_parameters(path, loader, params, name, "", seen)
                yield name, params
                continue
            if id(value) in chain:
                raise _fail(path, value, f"key '{name}' holds itself (a YAML alias of a mapping around it)")
            if entries:
                yield from _check_names(path, loader, value, name, seen, (*chain, id(value)))
                continue
        raise _fail(path, value, f"key '{name}' must hold '{PARAMS_KEY}:' (a node's parameters) or node names "
                                 f"under a namespace, not {_kind(value)}")


def _name_key(path: Path, key: yaml.Node, prefix: str) -> str:
    """The node name (``prefix/key``) a key gives, checked by rcl's rule."""
    if not isinstance(key, yaml.ScalarNode) or key.tag != _STR:
        shown = key.value if isinstance(key, yaml.ScalarNode) else _kind(key)
        raise _fail(path, key, f"key {shown!r}: a node name is a string of letters, digits and _ "
                               "that does not start with a digit")
    text = key.value
    name = f"{prefix}/{text}" if prefix else text
    if text == PARAMS_KEY:
        raise _fail(path, key, f"key '{name}': '{PARAMS_KEY}:' goes under a node name "
                               f"(e.g. '/**:' for every node)")
    tokens = text.split("/")
    if tokens[0] == "":
        tokens = tokens[1:]
    if not tokens or not all(_NAME_TOKEN.fullmatch(t) for t in tokens):
        raise _fail(path, key, f"key '{name}': a node name or namespace is '/'-separated names of letters, "
                               "digits and _ not starting with a digit, or the wildcards * and **")
    return name


def _check_parameters(path: Path, loader: yaml.SafeLoader, mapping: yaml.MappingNode, node_name: str,
                      prefix: str, seen: set[int]) -> None:
    """Check the parameters of ``node_name`` whose names start with ``prefix`` (dotted)."""
    if id(mapping) in seen:
        return
    seen.add(id(mapping))
    for key, value in _items(loader, mapping):
        if not isinstance(key, yaml.ScalarNode) or key.tag == _NULL or not key.value:
            raise _fail(path, key, f"'{node_name}': a parameter name must be text, not {_kind(key)}")
        name = f"{prefix}.{key.value}" if prefix else str(key.value)
        if isinstance(value, yaml.MappingNode):
            _check_parameters(path, loader, value, node_name, name, seen)
        elif isinstance(value, yaml.SequenceNode):
            _check_list(path, value, f"parameter '{name}' of '{node_name}'")
        elif value.tag == _NULL:
            raise _fail(path, value, f"parameter '{name}' of '{node_name}' has no value "
                                     "(give a value, or remove the line)")


def _check_list(path: Path, node: yaml.SequenceNode, name: str) -> None:
    """``name``: how messages name the parameter."""
    types: list[str] = []
    for item in node.value:
        if not isinstance(item, yaml.ScalarNode) or item.tag == _NULL:
            raise _fail(path, item, f"{name}: a list parameter holds scalars of one type "
                                    f"(bool, integer, double or string), not {_kind(item)}")
        kind = _TYPES.get(item.tag, "string")
        if types and kind != types[0]:
            hint = " (write integers as 1.0 in a list of doubles)" if {kind, types[0]} == {"integer", "double"} \
                else ""
            raise _fail(path, item, f"{name}: a list's items must be of one type: {item.value!r} "
                                    f"is a {kind} after {types[0]} items{hint}")
        types.append(kind)


def parameter_file_arguments(args: Sequence[str]) -> list[Path]:
    """The files given as ``--params-file FILE`` in the ``--ros-args`` parts of a command line."""
    files: list[Path] = []
    in_ros_args = False
    for i, arg in enumerate(args):
        if arg == "--ros-args":
            in_ros_args = True
        elif arg == "--":
            in_ros_args = False
        elif in_ros_args and arg == "--params-file" and i + 1 < len(args):
            files.append(Path(args[i + 1]))
    return files


def _flattened(params: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested parameter mappings as dotted names (``laser: {max_beams: 60}`` -> ``laser.max_beams``)."""
    flat: dict[str, Any] = {}
    for key, value in params.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, dict):
            flat.update(_flattened(value, name))
        else:
            flat[name] = value
    return flat


def _name_pattern(key: str) -> re.Pattern[str]:
    """The node names a file's key applies to, as rcl matches them: ``*`` one token, ``**`` any
    number; a key without a leading ``/`` is from the root namespace."""
    tokens = key.lstrip("/").split("/")
    parts = ["(/[^/]+)*" if t == "**" else "/[^/]+" if t == "*" else "/" + re.escape(t) for t in tokens]
    return re.compile("".join(parts))


def node_parameters(nodes: dict[str, dict[str, Any]], node: str) -> dict[str, Any]:
    """The parameters a file (:func:`check_parameter_file`'s result) gives node ``node`` (its fully
    qualified name, e.g. ``/amcl``), by dotted name: the keys with wildcards that match it (``/**``),
    then its own name's, each in the file's order, so that its own name's win wherever they are."""
    fqn = node if node.startswith("/") else "/" + node
    params: dict[str, Any] = {}
    keys = sorted(nodes, key=lambda k: "*" not in k)  # stable: wildcards first, each in the file's order
    for key in keys:
        if _name_pattern(key).fullmatch(fqn):
            params.update(_flattened(nodes[key]))
    return params


def is_static_layer(name: object, plugin: object) -> bool:
    """Whether the costmap layer ``name`` with ``plugin`` (its ``plugin`` parameter, or None) is
    Nav2's StaticLayer, which waits for a /map: named ``static_layer`` or of that plugin type."""
    return name == "static_layer" or "StaticLayer" in str(plugin or "")
