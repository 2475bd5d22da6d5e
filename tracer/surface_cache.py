"""The surface-tree cache (Lischinski & Gonczarowski 1990, section 4): the upper levels of each
patch's subdivision tree kept across rays.

A node is a slot of the thread's sub-patch arrays past the working slots: its control points,
box, bounds and place in the tree, exactly as the search would have them when it pops that
sub-patch. A search starts from the patch's cached root and walks cached nodes with the same
steps (criterion, slab and hull tests) it applies to computed ones; where a node's halves are
not cached yet (down to `cache_depth` levels) it computes them once, from a working copy, and
keeps them; below that depth it goes on in working slots as without the cache. A ray whose
tests miss every cached node under the root rejects the patch without computing a box.

Nodes come in pairs (the two halves of a split; a root takes a pair of its own) from a pool
bounded by `cache_mb`; when the pool runs out, the least recently searched patch's tree is
released first (a queue over patches, moved to the back at each search). Each render thread has
a cache of its own (no locks), kept across work units and frames while the geometry and the
options that shape the trees stay the same (render.py).

What is cached is the tree the box alone decides: under the float, fixed and mantissa criteria
with the `length` split a search with the cache is the search without it, box for box. Where the
ray takes part in choosing a split direction (the adaptive criterion's threshold of detail, the
`cross` split), the first search that reaches a node decides its halves for later rays.

Per ray, the counters of a tile kernel (cache hits: searches that found the patch's tree; misses:
searches that had to make its root) are the growth of the cache's own running totals.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from .jit import njit

# root (n_leaves,) int32: the patch's cached root slot or -1; child (nodes,) int32: the first of
# a node's two cached halves (slot) or -1; lru_prev, lru_next (n_leaves,) int32: the queue of
# patches with a tree, least recently searched first; pairs_free (pairs,) int32: a stack of
# free pair indices; evict (nodes + 2,) int32: the release walk's stack; stack (working,) uint32:
# the search's stack of slots; free_slots (working,) uint32: working slots not in use (unsigned,
# as bundle.py's: no negative-index fix-ups); seen
# (n_leaves,) uint8: 1 for each patch searched since the renderer last cleared it (the surfaces a
# frame searched, for its misses per surface); state int64: see S_*.
CacheRecord = namedtuple("CacheRecord", "root child lru_prev lru_next pairs_free evict stack free_slots seen state")
S_FIRST, S_FREE_PAIRS, S_HEAD, S_TAIL, S_DEPTH, S_HITS, S_MISSES, S_NODES, S_RELEASES = range(9)
STATE_LEN = 9

# Bytes a cached node takes beyond its points: box (6 float64), bounds (subpatch.MF_LEN float64),
# tree place (subpatch.MI_LEN int32) and its child link.
NODE_OVERHEAD = 6 * 8 + 17 * 8 + 5 * 4 + 4


def node_bytes(max_points: int, point_bytes: int) -> int:
    return 4 * max_points * point_bytes + NODE_OVERHEAD


def point_bytes(dtype, rational: bool) -> int:
    """Bytes a control point's coordinate takes in a node: the working precision's, and a float64
    copy beside float32 ones where rational patches are searched in float64."""
    size = np.dtype(dtype).itemsize
    return size + (8 if rational and size != 8 else 0)


def mib_for_every_tree(n_leaves: int, max_points: int, dtype, rational: bool, depth: int) -> float:
    """A cache_mb that holds every patch's whole tree `depth` levels deep (a root pair and a pair of
    halves for each node above that depth): a cache that never releases a tree."""
    pairs = n_leaves * (2 ** depth + 1)
    return pairs * 2 * node_bytes(max_points, point_bytes(dtype, rational)) / 2 ** 20


def new_cache(n_leaves: int, working: int, pairs: int, depth: int) -> CacheRecord:
    """An empty cache for a scene of n_leaves patches: `working` slots come first (the cache's
    nodes are the slots from there on), `pairs` pairs of nodes, trees `depth` levels deep."""
    nodes = 2 * pairs
    state = np.zeros(STATE_LEN, np.int64)
    state[S_FIRST] = working
    state[S_FREE_PAIRS] = pairs
    state[S_HEAD] = state[S_TAIL] = -1
    state[S_DEPTH] = depth
    return CacheRecord(np.full(n_leaves, -1, np.int32), np.full(nodes, -1, np.int32),
                       np.full(n_leaves, -1, np.int32), np.full(n_leaves, -1, np.int32),
                       np.arange(pairs, dtype=np.int32)[::-1].copy(), np.zeros(nodes + 2, np.int32),
                       np.zeros(working, np.uint32), np.arange(working, dtype=np.uint32),
                       np.zeros(n_leaves, np.uint8), state)


def no_cache() -> CacheRecord:
    """The stand-in record of kernels built without the cache (never used)."""
    return new_cache(1, 1, 1, 0)


@njit(cache=True, nogil=True, _nrt=False)
def _unlink(cache, p):
    prev = cache.lru_prev[p]
    nxt = cache.lru_next[p]
    if prev >= 0:
        cache.lru_next[prev] = nxt
    elif cache.state[S_HEAD] == p:
        cache.state[S_HEAD] = nxt
    if nxt >= 0:
        cache.lru_prev[nxt] = prev
    elif cache.state[S_TAIL] == p:
        cache.state[S_TAIL] = prev
    cache.lru_prev[p] = -1
    cache.lru_next[p] = -1


@njit(cache=True, nogil=True, _nrt=False)
def touch(cache, p):
    """Patch p was just searched: to the back of the queue."""
    cache.seen[p] = 1
    if cache.state[S_TAIL] == p:
        return
    _unlink(cache, p)
    tail = cache.state[S_TAIL]
    cache.lru_prev[p] = tail
    if tail >= 0:
        cache.lru_next[tail] = p
    else:
        cache.state[S_HEAD] = p
    cache.state[S_TAIL] = p


@njit(cache=True, nogil=True, _nrt=False)
def _free_pair(cache, node):
    first = cache.state[S_FIRST]
    cache.pairs_free[cache.state[S_FREE_PAIRS]] = (node - first) // 2
    cache.state[S_FREE_PAIRS] += 1
    cache.state[S_NODES] -= 2


@njit(cache=True, nogil=True, _nrt=False)
def release(cache, p):
    """Release patch p's tree (all its node pairs) and take it off the queue."""
    first = cache.state[S_FIRST]
    stack = cache.evict
    node = cache.root[p]
    if node < 0:
        return
    _free_pair(cache, node)
    stack[0] = node
    top = 1
    while top > 0:
        top -= 1
        node = stack[top]
        kid = cache.child[node - first]
        if kid >= 0:
            cache.child[node - first] = -1
            _free_pair(cache, kid)
            stack[top] = kid
            stack[top + 1] = kid + 1
            top += 2
    cache.root[p] = -1
    cache.state[S_RELEASES] += 1
    _unlink(cache, p)


@njit(cache=True, nogil=True, _nrt=False)
def take_pair(cache, keep):
    """The first slot of a free pair of nodes, releasing the least recently searched trees (never
    patch `keep`'s, the one being searched) until one is free; -1 if none can be."""
    while cache.state[S_FREE_PAIRS] == 0:
        victim = cache.state[S_HEAD]
        if victim < 0 or victim == keep:
            return -1
        release(cache, victim)
    cache.state[S_FREE_PAIRS] -= 1
    cache.state[S_NODES] += 2
    return cache.state[S_FIRST] + 2 * cache.pairs_free[cache.state[S_FREE_PAIRS]]


@njit(cache=True, nogil=True, inline='always')
def copy_slot(sl, src, dst, ncoord, count):
    """Slot src's points, box, bounds and tree place into slot dst."""
    _copy_slot(sl.buf, sl.box, sl.mf, sl.mi, src, dst, ncoord, count)


@njit(cache=True, nogil=True, _nrt=False)
def _copy_slot(buf, box, mf, mi, src, dst, ncoord, count):
    """copy_slot's call, given Slots' arrays, not the record (subpatch._CALLED)."""
    for c in range(ncoord):
        for k in range(count):
            buf[dst, c, k] = buf[src, c, k]
    for k in range(box.shape[1]):
        box[dst, k] = box[src, k]
    for k in range(mf.shape[1]):
        mf[dst, k] = mf[src, k]
    for k in range(mi.shape[1]):
        mi[dst, k] = mi[src, k]


@njit(cache=True, nogil=True, inline='always')
def keep_halves(sl, cache, node, a, b, kid, ncoord, count, free, nfree):
    """The halves just computed in working slots a and b become cached node's children, the pair
    kid, kid + 1; a and b go back to the free working slots (free[:nfree]). Returns their count."""
    first = cache.state[S_FIRST]
    copy_slot(sl, a, kid, ncoord, count)
    copy_slot(sl, b, kid + 1, ncoord, count)
    cache.child[node - first] = kid
    cache.child[kid - first] = -1
    cache.child[kid + 1 - first] = -1
    free[nfree] = b
    free[nfree + 1] = a
    return nfree + 2


class ThreadCache:
    """One render thread's cache: the sub-patch arrays (the working slots, then the nodes) and the
    record of the trees in them, kept from one kernel call to the next."""

    def __init__(self, n_leaves: int, working: int, max_points: int, dtype, rational: bool, mib: float,
                 depth: int):
        pairs = max(1, int(mib * 2 ** 20) // (2 * node_bytes(max_points, point_bytes(dtype, rational))))
        slots = working + 2 * pairs
        self.buf = np.zeros((slots, 4, max_points), dtype)
        if self.buf.dtype == np.float64:
            self.buf64 = self.buf
        else:
            self.buf64 = np.zeros((slots, 4, max_points) if rational else (1, 4, 1))
        self.box = np.zeros((slots, 6))
        from .subpatch import MF_LEN, MI_LEN
        self.mf = np.zeros((slots, MF_LEN))
        self.mi = np.zeros((slots, MI_LEN), np.int32)
        self.record = new_cache(n_leaves, working, pairs, depth)

    @property
    def nbytes(self) -> int:
        arrays = (self.buf, self.box, self.mf, self.mi) + ((self.buf64,) if self.buf64 is not self.buf else ())
        return sum(a.nbytes for a in arrays + tuple(self.record))

    def map_pages(self) -> None:
        """Write the zero-filled arrays once, so the system maps their memory now and not while a
        frame is timed (np.zeros leaves that to the first write)."""
        for a in (self.buf, self.box, self.mf, self.mi, self.buf64, self.record.evict):
            a.fill(0)

    def summary(self) -> dict:
        """Running totals (searches that found a tree, that made one; trees released), the nodes
        held and their capacity, bytes, and the surfaces searched since `seen` was last cleared."""
        state = self.record.state
        return {"hits": int(state[S_HITS]), "misses": int(state[S_MISSES]), "nodes": int(state[S_NODES]),
                "released": int(state[S_RELEASES]), "capacity": int(len(self.record.child)), "bytes": self.nbytes,
                "surfaces": int(np.count_nonzero(self.record.seen))}
