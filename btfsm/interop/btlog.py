"""BehaviorTree.CPP 4 FileLogger2 recordings (``.btlog``, the files Groot2 replays) in.

``read_btlog(data, name)`` reads the bytes of a ``.btlog`` file and returns a ``BtLog``:
the tree BehaviorTree.CPP ran (its XML, as written by ``WriteTreeToXML`` with metadata: every
node carries its ``_uid``, every SubTree instance is its own ``<BehaviorTree _fullpath>``)
and the recorded status transitions ``(microseconds since the log started, node uid,
status)``. The format (BehaviorTree.CPP 4's ``src/loggers/bt_file_logger_v2.cpp``, read at
4.8.2, the version ``behaviortreepy`` 0.1.4 bundles, and at 4.10.0):

====================  =====================================================================
bytes                 content
====================  =====================================================================
18                    ``BTCPP4-FileLogger2``
1                     protocol version (1)
4                     N: the length of the XML (little-endian int32)
N                     the tree's XML
8                     the time the log started (microseconds since the epoch, int64)
9 each                a transition: 6 bytes time since the start (microseconds), 2 bytes
                      node uid, 1 byte status (0 IDLE, 1 RUNNING, 2 SUCCESS, 3 FAILURE,
                      4 SKIPPED)
====================  =====================================================================

FileLogger2 records every status change of every node (``TreeNode::setStatus`` and
``resetStatus`` when the status differs), transitions to IDLE included. A malformed file is
a ``ModelError`` naming the file, the byte offset and the problem.

>>> import struct
>>> xml = b'<root BTCPP_format="4"><BehaviorTree ID="T" _fullpath=""><Ok name="Ok" _uid="1"/></BehaviorTree></root>'
>>> data = b"BTCPP4-FileLogger2\\x01" + struct.pack("<i", len(xml)) + xml + struct.pack("<q", 0)
>>> data += (12).to_bytes(6, "little") + (1).to_bytes(2, "little") + bytes([2])
>>> log = read_btlog(data, "run.btlog")
>>> log.transitions, log.nodes[1].tag, log.nodes[1].name
([(12, 1, 2)], 'Ok', 'Ok')
>>> read_btlog(data[:-3], "run.btlog")
Traceback (most recent call last):
btfsm.errors.ModelError: run.btlog: byte 134: the file ends inside a transition (6 of its 9 bytes)
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, field

from ..errors import ModelError
from .btcpp_import import parse_xml

__all__ = ["BtLog", "LogNode", "read_btlog", "MAGIC", "STATUS_NAMES"]

MAGIC = b"BTCPP4-FileLogger2"
STATUS_NAMES = ("IDLE", "RUNNING", "SUCCESS", "FAILURE", "SKIPPED")
MAX_XML = 64 * 1024 * 1024  # bytes of embedded XML


@dataclass
class LogNode:
    """One node of the recorded tree: its uid, registration name (the XML tag), name,
    parent and children (a SubTree node's child is the root of its instance's tree)."""
    uid: int
    tag: str
    name: str
    path: str  # where it is in the log's XML, for messages
    parent: "LogNode | None" = None
    children: list = field(default_factory=list)

    def __repr__(self) -> str:
        return f"LogNode({self.uid}, {self.tag} {self.name!r})"


@dataclass
class BtLog:
    """A FileLogger2 recording: ``root`` of the recorded tree, ``nodes`` by uid, the
    start time (microseconds since the epoch) and ``transitions`` ``(usec, uid, status)``."""
    xml: bytes
    root: LogNode
    nodes: dict
    start_usec: int
    transitions: list


def read_btlog(data: bytes, name: str) -> BtLog:
    """The ``BtLog`` in the bytes of a ``.btlog`` file (see the module doc)."""
    def fail(offset, problem):
        return ModelError(f"byte {offset}", problem, name)

    if not data.startswith(MAGIC):
        raise ModelError("", f"not a BehaviorTree.CPP FileLogger2 log (it does not start with '{MAGIC.decode()}')", name)
    pos = len(MAGIC)
    if len(data) < pos + 5:
        raise fail(len(data), "the file ends inside the header")
    if data[pos] != 1:
        raise fail(pos, f"FileLogger2 protocol version {data[pos]}: only version 1 is read")
    pos += 1
    (size,) = struct.unpack_from("<i", data, pos)
    if size <= 0 or size > MAX_XML:
        raise fail(pos, f"XML length {size}: expected 1 to {MAX_XML} bytes")
    pos += 4
    if len(data) < pos + size + 8:
        raise fail(len(data), f"the file ends inside the tree's XML or the start time ({size} bytes of XML announced)")
    xml = data[pos:pos + size]
    try:
        doc = parse_xml(xml, name)
    except ModelError as exc:
        raise ModelError(f"the tree's XML (byte {pos}): {exc.element}".rstrip(": "), exc.problem, name) from None
    root, nodes = _tree_of(doc, name)
    pos += size
    (start,) = struct.unpack_from("<q", data, pos)
    pos += 8
    rest = len(data) - pos
    if rest % 9:
        raise fail(pos + rest - rest % 9, f"the file ends inside a transition ({rest % 9} of its 9 bytes)")
    transitions = []
    for k in range(rest // 9):
        off = pos + 9 * k
        usec = int.from_bytes(data[off:off + 6], "little")
        uid = int.from_bytes(data[off + 6:off + 8], "little")
        status = data[off + 8]
        if uid not in nodes:
            raise fail(off, f"transition {k + 1}: node uid {uid} is not in the log's tree")
        if status >= len(STATUS_NAMES):
            raise fail(off, f"transition {k + 1}: status {status} (expected 0 IDLE to 4 SKIPPED)")
        transitions.append((usec, uid, status))
    return BtLog(xml, root, nodes, start, transitions)


def _tree_of(doc, name) -> tuple:
    """(root LogNode, {uid: LogNode}) of the XML that FileLogger2 embeds."""
    def fail(problem):
        return ModelError("the tree's XML", problem, name)

    if doc.tag != "root":
        raise fail(f"<{doc.tag}>: expected <root>")
    trees = {}
    for el in doc.children:
        if el.tag == "BehaviorTree":
            path = el.attrs.get("_fullpath")
            if path is None:
                raise fail(f"{el.where()}: a BehaviorTree without _fullpath (not written by FileLogger2)")
            if path in trees:
                raise fail(f"{el.where()}: two trees with _fullpath '{path}'")
            if len(el.children) != 1:
                raise fail(f"{el.where()}: expected one root node")
            trees[path] = el
    if "" not in trees:
        raise fail("no <BehaviorTree _fullpath=\"\"> (the main tree)")
    nodes: dict = {}

    def build(el, parent, where, depth):
        uid_text = el.attrs.get("_uid")
        try:
            uid = int(uid_text)
        except (TypeError, ValueError):
            raise fail(f"{el.where()}: a node without a valid _uid ({uid_text!r})") from None
        if uid in nodes:
            raise fail(f"{el.where()}: _uid {uid} is used twice")
        label = el.attrs.get("name") or el.attrs.get("ID") or el.tag
        node = LogNode(uid, el.tag, label, f"{where}/{label}" if where else label, parent)
        nodes[uid] = node
        if parent is not None:
            parent.children.append(node)
        if el.tag == "SubTree":
            sub = trees.get(el.attrs.get("_fullpath", ""))
            if sub is None or el.children or depth > 100:
                raise fail(f"{el.where()}: a SubTree whose instance (_fullpath '{el.attrs.get('_fullpath')}') "
                           "is not in the log")
            build(sub.children[0], node, node.path, depth + 1)
        else:
            for c in el.children:
                build(c, node, node.path, depth + 1)
        return node

    return build(trees[""].children[0], None, "", 0), nodes
