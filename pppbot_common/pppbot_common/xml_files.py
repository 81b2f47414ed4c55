"""XML from users' files (URDF, SDF, model.config, COLLADA), read so that a file from a stranger
cannot reach beyond itself.

An XML document may declare entities in its DOCTYPE: an external one (``SYSTEM "file:///…"``)
pulls another file, or a URL, into the text (XXE); nested internal ones expand exponentially
("billion laughs"). No URDF, SDF or COLLADA file needs either, so a document that declares an
entity is refused with one message naming the file and line, before anything is read from it.
The parser loads no DTD, resolves no entity, fetches nothing over the network and keeps
libxml2's limits on depth and text size (``huge_tree`` off).
"""
from __future__ import annotations

from pathlib import Path

from lxml import etree

from pppbot_common.errors import PppbotError

_ENTITY = ("declares an entity (<!ENTITY ...>): refused, as an entity can read other files or expand "
           "without bound; write its text out instead")


class XmlFileError(PppbotError, ValueError):
    """A user's XML file that is malformed or declares entities; the message names file and line."""


def _parser() -> etree.XMLParser:
    return etree.XMLParser(remove_comments=True, resolve_entities=False, load_dtd=False, no_network=True,
                           huge_tree=False)


def refuse_entities(data: bytes, name: str) -> None:
    """Refuse a document that declares an entity, naming ``name`` and the line (for XML another
    library parses: xacro's). One that only mentions ``<!ENTITY`` in a comment or a text passes.

    Raises:
        XmlFileError: ``data`` declares an entity, or names one and is malformed.
    """
    if b"<!ENTITY" not in data:
        return
    # Named, but perhaps only in a comment or a text: the document's own DTD says (libxml2 reads
    # the declarations without expanding one).
    doctype = data.find(b"<!DOCTYPE")
    declaration = data.find(b"<!ENTITY", doctype) if doctype >= 0 else -1
    try:
        root = etree.fromstring(data, _parser())
    except etree.XMLSyntaxError as exc:
        if declaration < 0:
            raise XmlFileError(f"{name}:{exc.lineno}: malformed XML: {exc.msg}") from exc
        root = None  # (malformed by its entity, most likely: one used where it may not be)
    if (root is None and declaration >= 0) or (root is not None and _declares_entities(root)):
        line = data[:max(declaration, doctype, 0)].count(b"\n") + 1
        raise XmlFileError(f"{name}:{line}: {_ENTITY}")


def _declares_entities(root: etree._Element) -> bool:
    """Whether the document's own DTD declares an entity (general or parameter)."""
    dtd = root.getroottree().docinfo.internalDTD
    return dtd is not None and any(True for _ in dtd.iterentities())


def parse_xml(source: Path | str | bytes, name: str | None = None) -> etree._Element:
    """The root element of an XML file (a path) or text (``str``/``bytes``), with comments left out.

    ``name`` is how messages call the document (the path by default).

    Raises:
        XmlFileError: unreadable, malformed, or declares entities.
    """
    if isinstance(source, Path):
        name = name or str(source)
        try:
            data = source.read_bytes()
        except OSError as exc:
            raise XmlFileError(f"{name}: cannot read ({exc.strerror or exc})") from exc
    else:
        data = source.encode() if isinstance(source, str) else source
    name = name or "<xml>"
    refuse_entities(data, name)
    try:
        root = etree.fromstring(data, _parser())
    except etree.XMLSyntaxError as exc:
        raise XmlFileError(f"{name}:{exc.lineno}: malformed XML: {exc.msg}") from exc
    if root is None:
        raise XmlFileError(f"{name}: no XML element in the file")
    if _declares_entities(root):  # declared in an encoding the byte check missed
        raise XmlFileError(f"{name}: {_ENTITY}")
    return root
