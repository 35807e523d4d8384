"""Node groups in shader trees, read through as Cycles reads them.

Cycles flattens a material's node groups before it compiles the tree (a Group node is
replaced by its tree; a link into the group's Group Input continues from what feeds the
Group node's input outside; scene/shader_graph.cpp). The converters (addon/materials.py,
addon/world.py) walk the tree socket by socket, so here the walk is made to see the
flattened tree without building it (a render may not write to bpy.data): `wrap` gives the
tree's output node as a proxy whose input sockets resolve their links through

- a Group node: into its tree, from the Group Output's input of the same identifier (the
  group interface's socket),
- a Group Input node: out to the input of the same identifier of the Group node the walk
  came in through (a stack of them: groups inside groups), and on from what feeds it,
- reroutes,

so every node the converters meet is a proxy that knows the groups around it. An input
that ends unlinked at a group boundary takes the value of the socket there (the Group
node's own input field, or the Group Output's), converted to the socket's type as
Blender converts (colour -> float: its luminance; vector -> float: the mean; float ->
colour / vector: the value in each channel). A node inside a group is named
"Group/Node" (the Group nodes' names, outermost first), so warnings say where it is.
"""
from __future__ import annotations

import numpy as np

MAX_HOPS = 256  # links followed for one socket (reroute chains, nested groups)
_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def wrap(node):
    """The proxy of a top-level node (the tree's output node), or None for None (a proxy
    stays itself)."""
    if node is None or isinstance(node, GroupNode):
        return node
    return GroupNode(node, ())


def _unwrap(x):
    return x._node if isinstance(x, GroupNode) else x


class GroupNode:
    """A node of a shader tree seen from inside the groups `ctx` (a tuple of Group nodes,
    outermost first): attributes are the node's, its sockets proxies (GroupSocket)."""

    __slots__ = ("_node", "_ctx")

    def __init__(self, node, ctx: tuple):
        object.__setattr__(self, "_node", node)
        object.__setattr__(self, "_ctx", ctx)

    def __getattr__(self, name):
        return getattr(self._node, name)

    def __setattr__(self, name, value):
        setattr(self._node, name, value)

    @property
    def name(self) -> str:
        if not self._ctx:
            return self._node.name
        return "/".join([g.name for g in self._ctx] + [self._node.name])

    @property
    def inputs(self):
        return GroupSockets(self._node.inputs, self._ctx)

    @property
    def outputs(self):
        return GroupSockets(self._node.outputs, self._ctx)

    @property
    def internal_links(self):
        """The node's internal links (what a muted node passes through), from its input
        proxies (their links followed out of the groups) to its outputs."""
        out = []
        for link in getattr(self._node, "internal_links", ()):
            ident = link.from_socket.identifier
            frm = next((s for s in self.inputs if s.identifier == ident), None)
            if frm is not None:
                out.append(GroupLink(self, frm, link.to_socket))
        return out

    def _key(self):
        return (self._node.as_pointer(), tuple(g.as_pointer() for g in self._ctx))

    def __eq__(self, other):
        return isinstance(other, GroupNode) and self._key() == other._key()

    def __hash__(self):
        return hash(self._key())

    def __repr__(self):
        return f"GroupNode({self.name!r}, {self._node.type})"


class GroupSockets:
    """A node's inputs or outputs as GroupSocket proxies: by name, index, get, iteration."""

    __slots__ = ("_sockets", "_ctx")

    def __init__(self, sockets, ctx):
        self._sockets, self._ctx = sockets, ctx

    def __getitem__(self, key):
        if isinstance(key, slice):
            return [GroupSocket(s, self._ctx) for s in self._sockets[key]]
        return GroupSocket(self._sockets[key], self._ctx)

    def get(self, key, default=None):
        s = self._sockets.get(key)
        return default if s is None else GroupSocket(s, self._ctx)

    def __iter__(self):
        return (GroupSocket(s, self._ctx) for s in self._sockets)

    def __len__(self):
        return len(self._sockets)

    def __contains__(self, key):
        return key in self._sockets

    def keys(self):
        return self._sockets.keys()


class GroupLink:
    """A resolved link: from_node / from_socket proxies; is_valid False when a link on
    the way is (Blender flags a link into an unavailable socket so; the callers decide)."""

    __slots__ = ("from_node", "from_socket", "to_socket", "is_valid")
    is_muted = False

    def __init__(self, from_node, from_socket, to_socket, is_valid=True):
        self.from_node, self.from_socket, self.to_socket = from_node, from_socket, to_socket
        self.is_valid = is_valid


class GroupSocket:
    """A socket seen from inside the groups `ctx`: `links` / `is_linked` follow reroutes
    and group boundaries to the node that produces the value (resolve); `default_value`
    is, for an input that ends unlinked at a boundary, the boundary socket's value."""

    __slots__ = ("_socket", "_ctx", "_resolved")

    def __init__(self, socket, ctx):
        object.__setattr__(self, "_socket", socket)
        object.__setattr__(self, "_ctx", ctx)
        object.__setattr__(self, "_resolved", None)

    def __getattr__(self, name):
        return getattr(self._socket, name)

    def __setattr__(self, name, value):
        setattr(self._socket, name, value)

    def _resolve(self):
        if self._resolved is None:
            object.__setattr__(self, "_resolved", resolve(self._socket, self._ctx))
        return self._resolved

    @property
    def node(self):
        return GroupNode(self._socket.node, self._ctx)

    @property
    def is_linked(self) -> bool:
        if self._socket.is_output:
            return self._socket.is_linked
        return self._resolve()[0] == "node"

    @property
    def links(self):
        if self._socket.is_output:
            return self._socket.links
        found = self._resolve()
        if found[0] != "node":
            return []
        _, node, out, ctx, valid = found
        return [GroupLink(GroupNode(node, ctx), GroupSocket(out, ctx), self, valid)]

    @property
    def default_value(self):
        own = self._socket
        found = self._resolve() if not own.is_output else ("value", own)
        source = found[1] if found[0] == "value" else own
        value = getattr(source, "default_value", None)
        if source is own or value is None:
            return getattr(own, "default_value")
        return convert_value(value, getattr(own, "type", ""), getattr(own, "default_value",
                                                                      None))

    def as_pointer(self):
        return self._socket.as_pointer()

    def __eq__(self, other):
        return (isinstance(other, GroupSocket) and self._socket == other._socket
                and self._ctx == other._ctx)

    def __hash__(self):
        return hash((self._socket.as_pointer(), tuple(g.as_pointer() for g in self._ctx)))


def _active_group_output(tree):
    outs = [n for n in tree.nodes if n.type == "GROUP_OUTPUT"]
    active = [n for n in outs if getattr(n, "is_active_output", False)]
    return (active or outs or [None])[0]


def _by_identifier(sockets, identifier):
    return next((s for s in sockets if s.identifier == identifier), None)


def resolve(socket, ctx: tuple):
    """Where an input socket's value comes from, seen from inside the groups ctx:
    ("node", node, output socket, ctx', valid) for the node producing it (reroutes and
    group boundaries passed; valid: every link on the way is valid), or ("value",
    socket') when it ends unlinked: socket' is the socket whose own value it takes
    (socket itself, or a Group node's input / a Group Output's input at the boundary
    where the link ended). A muted link ends it as unlinked (the consumer's own value, as
    Blender); a muted Group node or one without a tree is a node like any other (the
    converters warn)."""
    cur, value_socket, valid = socket, socket, True
    for _ in range(MAX_HOPS):
        if not cur.is_linked or not cur.links:
            return ("value", value_socket)
        link = cur.links[0]
        if getattr(link, "is_muted", False):
            return ("value", value_socket)
        valid = valid and bool(getattr(link, "is_valid", True))
        node, out = link.from_node, link.from_socket
        if node.type == "REROUTE":
            cur = node.inputs[0]
            continue
        if node.type == "GROUP" and getattr(node, "node_tree", None) is not None \
                and not getattr(node, "mute", False):
            gout = _active_group_output(node.node_tree)
            inner = None if gout is None else _by_identifier(gout.inputs, out.identifier)
            if inner is None:  # (an output the group's tree does not make: its default)
                return ("value", value_socket)
            cur, value_socket, ctx = inner, inner, ctx + (node,)
            continue
        if node.type == "GROUP_INPUT":
            if not ctx:
                return ("value", value_socket)
            group = ctx[-1]
            outer = _by_identifier(group.inputs, out.identifier)
            if outer is None:
                return ("value", value_socket)
            cur, value_socket, ctx = outer, outer, ctx[:-1]
            continue
        return ("node", node, out, ctx, valid)
    return ("value", value_socket)


def convert_value(value, to_type: str, like=None):
    """A socket value carried into a socket of type to_type (Blender's implicit
    conversions): to VALUE / INT / BOOLEAN a colour's luminance or a vector's mean; to
    RGBA (r, g, b, 1); to VECTOR (x, y, z); like: the receiving socket's own value (its
    length decides a colour's 3 or 4 channels)."""
    arr = np.asarray(value if np.ndim(value) else float(value), np.float64)
    if to_type in ("VALUE", "INT", "BOOLEAN"):
        if arr.ndim == 0:
            return float(arr)
        if arr.size >= 4:  # a colour
            return float(arr[:3] @ _LUMINANCE)
        return float(arr[:3].mean())
    if to_type == "RGBA":
        rgb = np.full(3, float(arr)) if arr.ndim == 0 else np.resize(arr[:3], 3)
        n = len(like) if like is not None and np.ndim(like) else 4
        return tuple(rgb) + ((1.0,) if n >= 4 else ())
    if to_type == "VECTOR":
        return tuple(np.full(3, float(arr))) if arr.ndim == 0 else tuple(np.resize(arr[:3], 3))
    return value
