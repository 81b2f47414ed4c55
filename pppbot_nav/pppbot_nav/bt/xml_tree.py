"""Loading behaviour trees from BehaviorTree.CPP 4 XML, as Nav2 Jazzy's trees are written.

A file is ``<root BTCPP_format="4" main_tree_to_execute="MainTree">`` (without ``BTCPP_format``,
read as 4 with a warning in :attr:`Tree.warnings`, as BehaviorTree.CPP 4 does) with one or more
``<BehaviorTree ID="...">`` (one root node each); a node is written by its type
(``<Sequence>``, ``<ComputePathToPose goal="{goal}"/>``) or, as BehaviorTree.CPP 3 did, as
``<Action ID="...">`` / ``<Condition>`` / ``<Control>`` / ``<Decorator>``; ``<SubTree ID="...">``
runs another tree of the file on a blackboard of its own, its attributes remapping that
tree's entries (``port="{entry}"``) or giving literals, ``_autoremap="true"`` sharing the rest.
``<TreeNodesModel>`` (what Groot reads) is left alone. Everything is checked at load, before
a tick: the format, every node's type, its ports (each attribute a known port, each required
port given, each literal one its kind takes) and its number of children; a mistake is named
with the file, the line, the node and what is known.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from lxml import etree

from pppbot_common.xml_files import XmlFileError, parse_xml
from pppbot_nav.bt.builtin import BUILTIN_NODES, SubTree
from pppbot_nav.bt.nav2_controls import NAV2_CONTROL_NODES
from pppbot_nav.bt.tree import Blackboard, NodeConfig, PortKind, Tree, TreeNode, as_bool, blackboard_key
from pppbot_nav.errors import BehaviorTreeError

#: element names that give the node's type in their ``ID`` (BehaviorTree.CPP 3's way, still read by 4)
_BY_ID = ("Action", "Condition", "Control", "Decorator")
_SUBTREES = ("SubTree", "SubTreePlus")


class TreeFactory:
    """Builds trees from XML with the nodes it knows: BehaviorTree.CPP's own, Nav2's controls, and
    ``nodes`` (name → class) added."""

    def __init__(self, nodes: Mapping[str, type[TreeNode]] | None = None) -> None:
        self.nodes: dict[str, type[TreeNode]] = {**BUILTIN_NODES, **NAV2_CONTROL_NODES, **(nodes or {})}

    def register(self, name: str, node_class: type[TreeNode]) -> None:
        """Add (or replace) the node type ``name``."""
        self.nodes[name] = node_class

    def load(self, source: Path | str | bytes, *, name: str | None = None, main_tree: str | None = None,
             clock: Callable[[], float] = lambda: 0.0, blackboard: Blackboard | None = None) -> Tree:
        """The tree in ``source`` (a path, or the XML as text): ``main_tree``, else the file's
        ``main_tree_to_execute``, else its only tree.

        Raises:
            BehaviorTreeError: unreadable or malformed XML, or a tree as described in the module's docstring.
        """
        name = name or (str(source) if isinstance(source, Path) else "<behavior tree>")
        try:
            root = parse_xml(source, name)
        except XmlFileError as exc:
            raise BehaviorTreeError(str(exc)) from exc
        return _Loader(self, root, name, clock).tree(main_tree, blackboard or Blackboard())


class _Loader:
    def __init__(self, factory: TreeFactory, root: etree._Element, name: str, clock: Callable[[], float]) -> None:
        self.factory = factory
        self.root = root
        self.name = name
        self.clock = clock
        if root.tag != "root":
            raise self.error(root, f"the document is <{root.tag}>; a behaviour tree file is "
                                   "<root BTCPP_format=\"4\"> holding <BehaviorTree> elements")
        version = root.get("BTCPP_format")
        #: what is worth saying but does not stop the load
        self.warnings: list[str] = []
        if version is None:  # as BehaviorTree.CPP 4: read as its own format, with a warning
            self.warnings.append(f"{name}:{root.sourceline}: <root> has no BTCPP_format: read as "
                                 "BehaviorTree.CPP 4's (BTCPP_format=\"4\")")
        elif version != "4":
            raise self.error(root, f"BTCPP_format is {version!r}: pppbot reads BehaviorTree.CPP 4's format "
                                   "(BTCPP_format=\"4\", as Nav2 Jazzy's trees)")
        self.trees: dict[str, etree._Element] = {}
        for element in root:
            if element.tag == "BehaviorTree":
                tree_id = element.get("ID")
                if not tree_id:
                    raise self.error(element, "a <BehaviorTree> needs an ID")
                if tree_id in self.trees:
                    raise self.error(element, f"two trees are called '{tree_id}'")
                self.trees[tree_id] = element
            elif element.tag == "include":
                raise self.error(element, "<include> is not supported: put the trees in one file")
            elif element.tag != "TreeNodesModel":
                raise self.error(element, f"<{element.tag}> does not belong in <root>: it holds <BehaviorTree> "
                                          "and <TreeNodesModel> elements")
        if not self.trees:
            raise self.error(root, "the file holds no <BehaviorTree>")

    def error(self, element: etree._Element, what: str) -> BehaviorTreeError:
        return BehaviorTreeError(f"{self.name}:{element.sourceline}: {what}")

    def tree(self, main_tree: str | None, blackboard: Blackboard) -> Tree:
        main = main_tree or self.root.get("main_tree_to_execute")
        if main is None:
            if len(self.trees) != 1:
                raise self.error(self.root, f"which tree runs? main_tree_to_execute is not set and the file "
                                            f"holds {len(self.trees)}: {', '.join(self.trees)}")
            main = next(iter(self.trees))
        if main not in self.trees:
            raise self.error(self.root, f"main tree '{main}' is not in the file; its trees: {', '.join(self.trees)}")
        tree = Tree(self.body(main, blackboard, (main,)), blackboard)
        tree.warnings = list(self.warnings)
        return tree

    def body(self, tree_id: str, blackboard: Blackboard, stack: tuple[str, ...]) -> TreeNode:
        element = self.trees[tree_id]
        children = list(element)
        if len(children) != 1:
            raise self.error(element, f"tree '{tree_id}' must have exactly one root node, not {len(children)}")
        return self.node(children[0], blackboard, stack)

    def node(self, element: etree._Element, blackboard: Blackboard, stack: tuple[str, ...]) -> TreeNode:
        tag = element.tag
        type_name = element.get("ID", "") if tag in _BY_ID or tag in _SUBTREES else tag
        if not type_name:
            raise self.error(element, f"<{tag}> needs an ID naming its node type")
        attributes = {key: value for key, value in element.attrib.items() if key not in ("ID", "name")}
        label = element.get("name") or type_name
        where = f"{self.name}:{element.sourceline}"
        if tag in _SUBTREES:
            return self.subtree(element, type_name, attributes, label, blackboard, stack)
        node_class = self.factory.nodes.get(type_name)
        if node_class is None:
            raise self.error(element, f"unknown node '{type_name}'; known: {', '.join(sorted(self.factory.nodes))}")
        scripted = sorted(key for key in attributes if key.startswith("_"))
        if scripted:
            raise self.error(element, f"'{label}': {', '.join(scripted)}: BehaviorTree.CPP's scripted "
                                      "preconditions and post-conditions are not supported")
        ports = {port.name: port for port in node_class.PORTS}
        for key in attributes:
            if key not in ports:
                known = ", ".join(ports) or "none"
                raise self.error(element, f"{type_name} '{label}' has no port '{key}'; its ports: {known}")
        for port in ports.values():
            if port.required and port.name not in attributes:
                raise self.error(element, f"{type_name} '{label}': port '{port.name}' is required")
        node = node_class(label, NodeConfig(attributes, blackboard, self.clock, where))
        for key, text in attributes.items():  # a literal its port refuses: now, not at the first tick
            port = ports[key]
            if blackboard_key(text) is not None:
                continue
            if port.kind is PortKind.OUTPUT:
                raise self.error(element, f"{type_name} '{label}': output port '{key}' must name a blackboard "
                                          f"entry ({{key}}), not '{text}'")
            node._convert(port, text)
        children = list(element)
        wanted = node_class.CHILDREN
        if (wanted is None and not children) or (wanted is not None and len(children) != wanted):
            need = "one or more children" if wanted is None else f"{wanted} child{'ren' if wanted != 1 else ''}"
            raise self.error(element, f"{type_name} '{label}' takes {need}, not {len(children)}")
        node.children = [self.node(child, blackboard, stack) for child in children]
        return node

    def subtree(self, element: etree._Element, tree_id: str, attributes: dict[str, Any], label: str,
                blackboard: Blackboard, stack: tuple[str, ...]) -> TreeNode:
        if tree_id not in self.trees:
            raise self.error(element, f"SubTree '{tree_id}' is not in the file; its trees: {', '.join(self.trees)}")
        if tree_id in stack:
            raise self.error(element, f"SubTree '{tree_id}' runs itself ({' -> '.join((*stack, tree_id))})")
        if list(element):
            raise self.error(element, f"SubTree '{label}' takes no children: its tree is '{tree_id}'")
        try:
            autoremap = as_bool(attributes.pop("_autoremap", "false"))
        except ValueError as exc:
            raise self.error(element, f"SubTree '{label}': _autoremap: {exc}") from exc
        scripted = sorted(key for key in attributes if key.startswith("_"))
        if scripted:
            raise self.error(element, f"SubTree '{label}': {', '.join(scripted)}: scripted conditions are not "
                                      "supported")
        inner = Blackboard(blackboard, attributes, autoremap)
        node = SubTree(label, NodeConfig({}, blackboard, self.clock, f"{self.name}:{element.sourceline}"))
        node.children = [self.body(tree_id, inner, (*stack, tree_id))]
        return node
