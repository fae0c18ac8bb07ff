# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The core's kernels compiled: the complex's and the operators' kernels and the intrinsic
Delaunay flip rounds, as an extension built by the install.

Each function here is the compiled twin of a numpy function beside its caller, with the same
arithmetic in the same order, so the two agree bit for bit (``tests/core/test_extension.py``).
Callers take it through :func:`decrun.core.extension.kernels` (unless the switch says ``numpy``):
machine code that loads with the module, in milliseconds. The extension is optional: an install
without a C compiler leaves it out, and the numpy twins do the work.
"""

import numpy as np

from libc.math cimport INFINITY, fabs, sqrt
from libc.stdint cimport int8_t, int32_t, int64_t, uint8_t

ctypedef fused index_t:
    int32_t
    int64_t


def sorted_rows(const int64_t[:, :] rows, Py_ssize_t n_vertices):
    """Twin of the numpy path of ``simplex_arrays.sorted_rows``: insertion sort of each row, its shift
    count the row's inversion count; (sorted rows, parity int8, smallest, largest, repeated,
    used (n_vertices,) bool: the entries of the rows within 0..n_vertices-1).
    ``rows`` in any layout (a mesh's Fortran-ordered faces are not copied first)."""
    cdef Py_ssize_t m = rows.shape[0], c = rows.shape[1], t, a, b
    ordered_array = np.empty((m, c), np.int64)
    parity_array = np.empty(m, np.int8)
    used_array = np.zeros(max(n_vertices, 0), np.bool_)
    cdef int64_t[:, ::1] ordered = ordered_array
    cdef int8_t[::1] parity = parity_array
    cdef uint8_t[::1] used = used_array.view(np.uint8)
    cdef int64_t smallest = rows[0, 0], largest = rows[0, 0], value
    cdef Py_ssize_t shifts
    cdef bint repeated = False
    cdef int64_t x, y, z, low, middle, high
    if c == 3:  # triangles: the same sorted rows and inversion parities without the shifting loop
        for t in range(m):
            x, y, z = rows[t, 0], rows[t, 1], rows[t, 2]
            shifts = (x > y) + (x > z) + (y > z)
            low = x if x < y else y
            high = y if x < y else x
            middle = z if z < high else high
            high = z if z > high else high
            middle = middle if middle > low else low
            low = z if z < low else low
            ordered[t, 0], ordered[t, 1], ordered[t, 2] = low, middle, high
            parity[t] = 1 if shifts % 2 == 0 else -1
            if low < smallest:
                smallest = low
            if high > largest:
                largest = high
            if low == middle or middle == high:
                repeated = True
            if low >= 0 and high < n_vertices:
                used[low] = 1
                used[middle] = 1
                used[high] = 1
            else:  # an entry out of range (the input check names it): the others are marked
                if low >= 0 and low < n_vertices:
                    used[low] = 1
                if middle >= 0 and middle < n_vertices:
                    used[middle] = 1
                if high >= 0 and high < n_vertices:
                    used[high] = 1
        return ordered_array, parity_array, smallest, largest, bool(repeated), used_array
    for t in range(m):
        shifts = 0
        for a in range(c):
            value = rows[t, a]
            b = a - 1
            while b >= 0 and ordered[t, b] > value:
                ordered[t, b + 1] = ordered[t, b]
                b -= 1
                shifts += 1
            ordered[t, b + 1] = value
        parity[t] = 1 if shifts % 2 == 0 else -1
        if ordered[t, 0] < smallest:
            smallest = ordered[t, 0]
        if ordered[t, c - 1] > largest:
            largest = ordered[t, c - 1]
        for a in range(1, c):
            if ordered[t, a] == ordered[t, a - 1]:
                repeated = True
        for a in range(c):
            if ordered[t, a] >= 0 and ordered[t, a] < n_vertices:
                used[ordered[t, a]] = 1
    return ordered_array, parity_array, smallest, largest, bool(repeated), used_array


cdef bint _triangle_edges(const int64_t[:, :] top, const int64_t[:, ::1] columns):
    """Whether the rows are the edge slots (0,1), (0,2), (1,2) of C-contiguous triangles."""
    return (top.shape[1] == 3 and columns.shape[0] == 3 and columns.shape[1] == 2 and top.strides[1] == 8
            and top.strides[0] == 24 and columns[0, 0] == 0 and columns[0, 1] == 1 and columns[1, 0] == 0
            and columns[1, 1] == 2 and columns[2, 0] == 1 and columns[2, 1] == 2)


cdef int64_t _bucket_triangle_edges(const int64_t[:, ::1] top, int bits, int64_t[::1] order,
                                    int64_t[::1] sorted_key, object counts):
    """The counting sort of :func:`group_packed` for the edge slots of triangles, its loops
    unrolled over the three slots: the same buckets, keys and stable order; the bucket bounds
    are written to ``counts[0]`` (a list); returns the largest leading entry."""
    cdef Py_ssize_t m = top.shape[0], t, v
    cdef int64_t x, y, z, largest = 0
    for t in range(m):  # leading entries: x (slots 0, 1) and y (slot 2)
        x, y = top[t, 0], top[t, 1]
        if x > largest:
            largest = x
        if y > largest:
            largest = y
    count_array = np.zeros(largest + 2, np.int64)
    cdef int64_t[::1] count = count_array
    for t in range(m):
        count[top[t, 0] + 1] += 2
        count[top[t, 1] + 1] += 1
    for v in range(largest + 1):
        count[v + 1] += count[v]
    position_array = count_array[:largest + 1].copy()
    cdef int64_t[::1] position = position_array
    cdef int64_t p
    for t in range(m):
        x, y, z = top[t, 0], top[t, 1], top[t, 2]
        p = position[x]
        order[p], sorted_key[p] = 3 * t, (x << bits) | y
        order[p + 1], sorted_key[p + 1] = 3 * t + 1, (x << bits) | z
        position[x] = p + 2
        p = position[y]
        order[p], sorted_key[p] = 3 * t + 2, (y << bits) | z
        position[y] = p + 1
    counts.append(count_array)
    return largest


def group_packed(const int64_t[:, :] top, const int64_t[:, ::1] columns, int bits):
    """Twin of ``simplex_arrays.group_rows_numpy``: the rows ``top[t, columns[s]]`` grouped
    by a stable counting sort on their leading entry and a stable sort of each bucket by the
    packed key; (unique, inverse, order, starts). ``top`` in any layout; a triangle mesh's edge
    slots take loops unrolled over the three slots (the same arithmetic and order)."""
    cdef Py_ssize_t m = top.shape[0], slots = columns.shape[0], width = columns.shape[1]
    cdef Py_ssize_t total = m * slots, t, s, q, i, v, a, b, low, high, groups, g
    cdef int64_t k, lead, largest = 0, item, item_key, packed
    cdef int shift = bits * (width - 1)
    order_array = np.empty(total, np.int64)
    sorted_array = np.empty(total, np.int64)
    cdef int64_t[::1] order = order_array
    cdef int64_t[::1] sorted_key = sorted_array
    cdef int64_t[::1] count, position
    cdef const int64_t[:, ::1] rows
    if _triangle_edges(top, columns):
        counts = []
        rows = np.asarray(top)
        largest = _bucket_triangle_edges(rows, bits, order, sorted_key, counts)
        count = counts[0]
    else:
        for t in range(m):  # the keys' leading entries: the buckets (no array of keys is kept)
            for s in range(slots):
                lead = top[t, columns[s, 0]]
                if lead > largest:
                    largest = lead
        count = np.zeros(largest + 2, np.int64)
        for t in range(m):
            for s in range(slots):
                count[top[t, columns[s, 0]] + 1] += 1
        for v in range(largest + 1):
            count[v + 1] += count[v]
        position = np.array(count[:largest + 1])
        for t in range(m):  # each row's packed key, scattered into its bucket in row order (stable)
            for s in range(slots):
                k = 0
                for q in range(width):
                    k = (k << bits) | top[t, columns[s, q]]
                lead = k >> shift
                i = t * slots + s
                order[position[lead]] = i
                sorted_key[position[lead]] = k
                position[lead] += 1
    for v in range(largest + 1):
        low, high = count[v], count[v + 1]
        if high - low <= 1:
            continue
        if high - low <= 32:  # simplex_arrays._SMALL_BUCKET: stable insertion sort by key
            for a in range(low + 1, high):
                item = order[a]
                item_key = sorted_key[a]
                b = a - 1
                while b >= low and sorted_key[b] > item_key:
                    order[b + 1] = order[b]
                    sorted_key[b + 1] = sorted_key[b]
                    b -= 1
                order[b + 1] = item
                sorted_key[b + 1] = item_key
        else:
            rank = np.argsort(sorted_array[low:high], kind="mergesort")
            order_array[low:high] = order_array[low:high][rank]
            sorted_array[low:high] = sorted_array[low:high][rank]
    groups = 0
    for a in range(total):
        if a == 0 or sorted_key[a] != sorted_key[a - 1]:
            groups += 1
    unique_array = np.empty((groups, width), np.int64)
    inverse_array = np.empty(total, np.int64)
    starts_array = np.empty(groups + 1, np.int64)
    cdef int64_t[:, ::1] unique = unique_array
    cdef int64_t[::1] inverse = inverse_array
    cdef int64_t[::1] starts = starts_array
    cdef int64_t mask = (<int64_t> 1 << bits) - 1
    g = -1
    for a in range(total):
        k = sorted_key[a]
        if a == 0 or k != sorted_key[a - 1]:
            g += 1
            starts[g] = a
            packed = k
            for q in range(width - 1, -1, -1):
                unique[g, q] = packed & mask
                packed >>= bits
        inverse[order[a]] = g
    starts[groups] = total
    return unique_array, inverse_array, order_array, starts_array


def _facet_pairs_fill(const int64_t[::1] order, const int64_t[::1] starts, const int64_t[:, :] top,
                      int64_t[::1] interior, index_t[::1] first, index_t[::1] second, index_t[::1] first_slot,
                      index_t[::1] second_slot):
    cdef Py_ssize_t width = top.shape[1], n = width - 1, groups = starts.shape[0] - 1, g, p = 0
    cdef int64_t a, b, ta, tb
    cdef bint suspect = False
    for g in range(groups):
        if starts[g + 1] - starts[g] != 2:
            continue
        a, b = order[starts[g]], order[starts[g] + 1]
        if width == 3:  # triangles: a division by a constant (a multiplication)
            ta, tb = a // 3, b // 3
        else:
            ta, tb = a // width, b // width
        interior[p] = g
        first[p], first_slot[p] = ta, a - ta * width
        second[p], second_slot[p] = tb, b - tb * width
        if top[ta, n - (a - ta * width)] == top[tb, n - (b - tb * width)]:
            suspect = True
        p += 1
    return bool(suspect)


def facet_pairs(order, starts, top, index_like):
    """Twin of ``complex.checks.facet_pairs_numpy``: the facets in exactly two top simplices
    (int64), their simplices and slots (``index_like``'s type), and the duplicate suspicion."""
    cdef const int64_t[::1] starts_view = starts
    cdef Py_ssize_t g, count = 0
    for g in range(starts_view.shape[0] - 1):
        if starts_view[g + 1] - starts_view[g] == 2:
            count += 1
    interior = np.empty(count, np.int64)
    first, second, first_slot, second_slot = (np.empty(count, index_like.dtype) for _ in range(4))
    suspect = _facet_pairs_fill(order, starts, top, interior, first, second, first_slot, second_slot)
    return (interior, first, second, first_slot, second_slot), suspect


cdef tuple _triangle_edge_groups(const int64_t[:, ::1] top, int bits):
    """:func:`facet_groups` for the edge slots of C-contiguous sorted triangles (int32 pairs):
    the counting sort of :func:`group_packed` whose buckets hold, for each slot, its second
    vertex and the vertex opposite it packed in one int64 (``second << 32 | opposite``): a
    bucket is sorted by the second vertex alone (the packed key's order within a bucket), and
    the pairs and their duplicate suspicion are read off the sorted buckets, without another
    pass over the groups or a look-up of the triangles; each slot's edge (``inverse``) is then
    looked up in triangle order among its leading vertex's edges (reads instead of writes
    scattered over ``inverse``)."""
    cdef Py_ssize_t m = top.shape[0], total = 3 * m, t, v, a, b, low, high, groups = 0, pairs = 0, g, p
    cdef int64_t x, y, z, at, item, item_load, item_second, ta, tb, oa, ob, largest = 0
    cdef int64_t low_half = 0xffffffff
    order_array = np.empty(total, np.int64)
    payload_array = np.empty(total, np.int64)
    cdef int64_t[::1] order = order_array
    cdef int64_t[::1] payload = payload_array
    # the entries are below 2**bits - 1 (bits fits the largest): the buckets' counts in an array of
    # that bound, the largest leading entry found while counting (no pass of its own)
    count_array = np.zeros((1 << bits) + 1, np.int64)
    cdef int64_t[::1] count = count_array
    for t in range(m):
        x, y = top[t, 0], top[t, 1]  # x leads slots 0 and 1, y slot 2
        count[x + 1] += 2
        count[y + 1] += 1
        if x > largest:
            largest = x
        if y > largest:
            largest = y
    for v in range(largest + 1):
        count[v + 1] += count[v]
    position_array = count_array[:largest + 1].copy()
    cdef int64_t[::1] position = position_array
    for t in range(m):  # slots (0,1), (0,2) into x's bucket, (1,2) into y's, in triangle order
        x, y, z = top[t, 0], top[t, 1], top[t, 2]
        at = position[x]
        order[at], payload[at] = 3 * t, (y << 32) | z
        order[at + 1], payload[at + 1] = 3 * t + 1, (z << 32) | y
        position[x] = at + 2
        at = position[y]
        order[at], payload[at] = 3 * t + 2, (z << 32) | x
        position[y] = at + 1
    for v in range(largest + 1):
        low, high = count[v], count[v + 1]
        if 1 < high - low <= 32:  # simplex_arrays._SMALL_BUCKET: stable insertion sort
            for a in range(low + 1, high):
                item = order[a]
                item_load = payload[a]
                item_second = item_load >> 32
                b = a - 1
                while b >= low and (payload[b] >> 32) > item_second:
                    order[b + 1] = order[b]
                    payload[b + 1] = payload[b]
                    b -= 1
                order[b + 1] = item
                payload[b + 1] = item_load
        elif high - low > 32:
            rank = np.argsort(payload_array[low:high] >> 32, kind="mergesort")
            order_array[low:high] = order_array[low:high][rank]
            payload_array[low:high] = payload_array[low:high][rank]
        a = low
        while a < high:  # the bucket's groups, and those of two slots (the pairs)
            b = a + 1
            while b < high and (payload[b] >> 32) == (payload[a] >> 32):
                b += 1
            groups += 1
            if b - a == 2:
                pairs += 1
            a = b
    unique_array = np.empty((groups, 2), np.int64)
    inverse_array = np.empty(total, np.int64)
    starts_array = np.empty(groups + 1, np.int64)
    interior_array = np.empty(pairs, np.int64)
    first_array, second_array, first_slot_array, second_slot_array = (np.empty(pairs, np.int32) for _ in range(4))
    cdef int64_t[:, ::1] unique = unique_array
    cdef int64_t[::1] inverse = inverse_array
    cdef int64_t[::1] starts = starts_array
    cdef int64_t[::1] interior = interior_array
    cdef int32_t[::1] first = first_array
    cdef int32_t[::1] second = second_array
    cdef int32_t[::1] first_slot = first_slot_array
    cdef int32_t[::1] second_slot = second_slot_array
    cdef bint suspect = False
    first_group_array = np.empty(largest + 1, np.int64)  # the first group (edge) of each bucket
    cdef int64_t[::1] first_group = first_group_array
    g = 0
    p = 0
    for v in range(largest + 1):
        low, high = count[v], count[v + 1]
        first_group[v] = g
        a = low
        while a < high:
            y = payload[a] >> 32
            starts[g] = a
            unique[g, 0] = v
            unique[g, 1] = y
            b = a + 1
            while b < high and (payload[b] >> 32) == y:
                b += 1
            if b - a == 2:
                oa, ob = order[a], order[a + 1]
                ta, tb = oa // 3, ob // 3
                interior[p] = g
                first[p], first_slot[p] = <int32_t> ta, <int32_t> (oa - 3 * ta)
                second[p], second_slot[p] = <int32_t> tb, <int32_t> (ob - 3 * tb)
                if (payload[a] & low_half) == (payload[a + 1] & low_half):  # the same opposite vertex
                    suspect = True
                p += 1
            g += 1
            a = b
    starts[groups] = total
    for t in range(m):  # each slot's edge, found in its leading vertex's few edges (read, where the
        x, y, z = top[t, 0], top[t, 1], top[t, 2]  # sorted order would scatter writes across inverse)
        g = first_group[x]
        while unique[g, 1] != y:
            g += 1
        inverse[3 * t] = g
        g = first_group[x]
        while unique[g, 1] != z:
            g += 1
        inverse[3 * t + 1] = g
        g = first_group[y]
        while unique[g, 1] != z:
            g += 1
        inverse[3 * t + 2] = g
    return ((unique_array, inverse_array, order_array, starts_array),
            (interior_array, first_array, second_array, first_slot_array, second_slot_array), bool(suspect))


def facet_groups(const int64_t[:, :] top, const int64_t[:, ::1] columns, int bits, index_like):
    """Twin of ``complex.checks.group_facets``' numpy path: :func:`group_packed`'s grouping of the facet
    slots, then :func:`facet_pairs` on it: ((unique, inverse, order, starts), pairs, suspect). The
    edge slots of C-contiguous triangles with int32 pairs take one fused counting sort (where the
    vertex indices are not much sparser than the slots: its buckets' counts span 2**bits)."""
    if (_triangle_edges(top, columns) and bits <= 31 and index_like.dtype == np.int32 and top.shape[0] > 0
            and (1 << bits) <= 6 * top.shape[0] + 2):  # the bucket counts' bound: at most twice the slots
        return _triangle_edge_groups(np.asarray(top), bits)
    groups = group_packed(top, columns, bits)
    pairs, suspect = facet_pairs(groups[2], groups[3], np.ascontiguousarray(top), index_like)
    return groups, pairs, suspect


def consistent(index_t[::1] first, index_t[::1] second, index_t[::1] first_slot, index_t[::1] second_slot,
               const int8_t[::1] parity):
    """Twin of ``complex.checks.inconsistent_facets`` (none): True when no interior facet is inconsistent."""
    cdef Py_ssize_t p
    cdef int s0, s1
    for p in range(first.shape[0]):
        s0 = parity[first[p]] if first_slot[p] % 2 == 0 else -parity[first[p]]
        s1 = parity[second[p]] if second_slot[p] % 2 == 0 else -parity[second[p]]
        if s0 == s1:
            return False
    return True


ctypedef fused corner_t:
    int32_t
    int64_t


cdef int64_t _unite_fans(const int64_t[:, ::1] top, index_t[::1] first, index_t[::1] second, index_t[::1] first_slot,
                         index_t[::1] second_slot, corner_t[::1] parent, int64_t[::1] result, bint per_vertex,
                         const int8_t[::1] parity, bint* consistent) noexcept:
    """A union–find of the corners, then each vertex's roots counted into
    ``result`` (``per_vertex``) or all the roots returned (:func:`fan_roots`); with a
    ``parity`` (not empty), ``consistent[0]`` cleared where a pair is inconsistent
    (:func:`consistent`'s test, in the same walk over the pairs)."""
    cdef Py_ssize_t m = top.shape[0], width = top.shape[1], n = width - 1, p, i0, i1, r, t, i, corner
    cdef int64_t t0, t1, skip0, skip1, merges = 0
    cdef corner_t a, b
    cdef bint oriented = parity.shape[0] > 0
    cdef int s0, s1
    for p in range(first.shape[0]):
        t0, t1 = first[p], second[p]
        if oriented:
            s0 = parity[t0] if first_slot[p] % 2 == 0 else -parity[t0]
            s1 = parity[t1] if second_slot[p] % 2 == 0 else -parity[t1]
            if s0 == s1:
                consistent[0] = False
        skip0, skip1 = n - first_slot[p], n - second_slot[p]
        i0 = 0
        i1 = 0
        for r in range(n):
            if i0 == skip0:
                i0 += 1
            if i1 == skip1:
                i1 += 1
            a = <corner_t> (t0 * width + i0)
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            b = <corner_t> (t1 * width + i1)
            while parent[b] != b:
                parent[b] = parent[parent[b]]
                b = parent[b]
            if a < b:
                parent[b] = a
                merges += 1
            elif b < a:
                parent[a] = b
                merges += 1
            i0 += 1
            i1 += 1
    if not per_vertex:  # each merge of two roots left one root fewer: no pass over the corners
        return m * width - merges
    for t in range(m):
        for i in range(width):
            corner = t * width + i
            if parent[corner] == corner:
                result[top[t, i]] += 1
    return 0


def fans(const int64_t[:, ::1] top, index_t[::1] first, index_t[::1] second, index_t[::1] first_slot,
         index_t[::1] second_slot, Py_ssize_t n_vertices):
    """Twin of ``complex.checks.fans_per_vertex``' numpy path: union–find over the corners ``(n+1)·t + i``; the
    fans of a vertex are its corners' distinct roots. (n0,) int64. The corners' parents are
    int32 where they fit (half the memory a fresh process must fault in)."""
    cdef Py_ssize_t corners = top.shape[0] * top.shape[1]
    cdef bint unasked = True
    cdef const int8_t[::1] no_parity = np.zeros(0, np.int8)
    fans_array = np.zeros(n_vertices, np.int64)
    if corners < 2**31 - 1:
        _unite_fans[index_t, int32_t](top, first, second, first_slot, second_slot,
                                      np.arange(corners, dtype=np.int32), fans_array, True, no_parity, &unasked)
    else:
        _unite_fans[index_t, int64_t](top, first, second, first_slot, second_slot,
                                      np.arange(corners, dtype=np.int64), fans_array, True, no_parity, &unasked)
    return fans_array


def fan_roots(const int64_t[:, ::1] top, index_t[::1] first, index_t[::1] second, index_t[::1] first_slot,
              index_t[::1] second_slot, const int8_t[::1] parity):
    """Compiled ``complex.checks.fan_roots_and_consistency``: (the roots of :func:`fans`' union–find, counted
    without reading which vertex each is; :func:`consistent`'s answer for ``parity``), in one walk
    over the pairs."""
    cdef Py_ssize_t corners = top.shape[0] * top.shape[1]
    cdef int64_t[::1] unused = np.zeros(0, np.int64)
    cdef int64_t roots
    cdef bint consistent = True
    if corners < 2**31 - 1:
        roots = _unite_fans[index_t, int32_t](top, first, second, first_slot, second_slot,
                                              np.arange(corners, dtype=np.int32), unused, False, parity, &consistent)
    else:
        roots = _unite_fans[index_t, int64_t](top, first, second, first_slot, second_slot,
                                              np.arange(corners, dtype=np.int64), unused, False, parity, &consistent)
    return roots, bool(consistent)


def small_volumes(const double[:, :] points, const int64_t[:, ::1] simplices):
    """Twin of ``simplex_arrays.vertex_volumes_numpy``: lengths of edges / areas of triangles
    from the (n0, d) coordinates, d = 2 or 3, in any layout (not copied; C order keeps a vertex's
    coordinates in one cache line). (m,) float64."""
    cdef Py_ssize_t m = simplices.shape[0], corners = simplices.shape[1], d = points.shape[1], t, axis
    cdef int64_t p, q, r
    cdef double total, diff, u0, u1, u2, v0, v1, v2, component
    out_array = np.empty(m)
    cdef double[::1] out = out_array
    for t in range(m):
        p = simplices[t, 0]
        q = simplices[t, 1]
        if corners == 2:
            total = 0.0
            for axis in range(d):
                diff = points[q, axis] - points[p, axis]
                total = total + diff * diff
            out[t] = sqrt(total)
            continue
        r = simplices[t, 2]
        if d == 2:
            u0, u1 = points[q, 0] - points[p, 0], points[q, 1] - points[p, 1]
            v0, v1 = points[r, 0] - points[p, 0], points[r, 1] - points[p, 1]
            out[t] = 0.5 * fabs(u0 * v1 - u1 * v0)
            continue
        u0, u1, u2 = points[q, 0] - points[p, 0], points[q, 1] - points[p, 1], points[q, 2] - points[p, 2]
        v0, v1, v2 = points[r, 0] - points[p, 0], points[r, 1] - points[p, 1], points[r, 2] - points[p, 2]
        total = 0.0
        component = u1 * v2 - u2 * v1
        total += component * component
        component = u2 * v0 - u0 * v2
        total += component * component
        component = u0 * v1 - u1 * v0
        total += component * component
        out[t] = sqrt(total) * 0.5
    return out_array


def triangle_dual(const double[:, :] points, const int64_t[:, :] top, const double[::1] area,
                  const int64_t[:, :] triangle_edges, Py_ssize_t n_edges, Py_ssize_t n_vertices):
    """Twin of ``stars.circumcentric.triangle_dual_volumes_numpy``: (dual0 (n0,), dual1 (n1,), edge lengths
    (n1,)) from the (n0, d) coordinates in any layout (not copied)."""
    dual0_array = np.zeros(n_vertices)
    dual1_array = np.zeros(n_edges)
    length_array = np.empty(n_edges)  # every edge is a triangle's: each written (with the same value)
    cdef double[::1] dual0 = dual0_array
    cdef double[::1] dual1 = dual1_array
    cdef double[::1] length = length_array
    cdef Py_ssize_t d = points.shape[1], t, axis
    cdef int64_t a, b, c
    cdef double sq0, sq1, sq2, dot0, dot1, dot2, x0, x1, x2, e0, e1, e2, factor, cot0, cot1, cot2, w0, w1, w2, l0, l1, l2
    for t in range(top.shape[0]):
        a, b, c = top[t, 0], top[t, 1], top[t, 2]
        sq0 = sq1 = sq2 = 0.0
        dot0 = dot1 = dot2 = 0.0
        for axis in range(d):
            x0, x1, x2 = points[a, axis], points[b, axis], points[c, axis]
            e0 = x2 - x1
            e1 = x0 - x2
            e2 = x1 - x0
            sq0 += e0 * e0
            sq1 += e1 * e1
            sq2 += e2 * e2
            dot0 += e1 * e2
            dot1 += e2 * e0
            dot2 += e0 * e1
        factor = -0.5 / area[t]
        cot0, cot1, cot2 = dot0 * factor, dot1 * factor, dot2 * factor
        l0, l1, l2 = sqrt(sq0), sqrt(sq1), sqrt(sq2)
        dual1[triangle_edges[t, 0]] += l2 * (0.5 * cot2)
        dual1[triangle_edges[t, 1]] += l1 * (0.5 * cot1)
        dual1[triangle_edges[t, 2]] += l0 * (0.5 * cot0)
        length[triangle_edges[t, 0]] = l2
        length[triangle_edges[t, 1]] = l1
        length[triangle_edges[t, 2]] = l0
        w0, w1, w2 = sq0 * cot0, sq1 * cot1, sq2 * cot2
        dual0[a] += (w2 + w1) * 0.125
        dual0[b] += (w0 + w2) * 0.125
        dual0[c] += (w1 + w0) * 0.125
    return dual0_array, dual1_array, length_array


def incidence(const int64_t[:, :] faces, const int8_t[::1] orientation, double[::1] data, index_t[::1] indices):
    """Twin of ``complex.simplicial_complex.incidence_entries_numpy``: δ_jᵀ's CSR entries, row by row."""
    cdef Py_ssize_t width = faces.shape[1], s, l
    cdef bint oriented = orientation.shape[0] > 0
    cdef double sign
    for s in range(faces.shape[0]):
        sign = 1.0
        if oriented:
            sign = 1.0 if orientation[s] > 0 else -1.0
        for l in range(width):
            indices[s * width + l] = faces[s, l]
            data[s * width + l] = sign if l % 2 == 0 else -sign
    return data.base, indices.base


cdef inline double _smaller(double a, double b) noexcept nogil:
    """Python's ``min(a, b)``: ``a`` unless ``b < a``."""
    return b if b < a else a


cdef inline double _larger(double a, double b) noexcept nogil:
    """Python's ``max(a, b)``: ``a`` unless ``b > a``."""
    return b if b > a else a


cdef inline double _heron_scalar(double x, double y, double z) noexcept nogil:
    """``intrinsic_delaunay._heron`` for one triangle, the same operations in the same order."""
    cdef double low_xy = _smaller(x, y), high_xy = _larger(x, y)
    cdef double a = _larger(high_xy, z), c = _smaller(low_xy, z)
    cdef double b = _larger(low_xy, _smaller(high_xy, z))
    cdef double product = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c))
    return 0.25 * sqrt(_larger(product, 0.0))


cdef double _edge_weight(int64_t e, const int64_t[:, :] sides, const int64_t[:, :] face_edges,
                         const double[:] lengths) noexcept nogil:
    """``intrinsic_delaunay._edge_weights`` of one interior edge: ½(cot α + cot β)."""
    cdef double total = 0.0, l0, l1, l2, s0, s1, s2, opposite
    cdef int64_t side, face, corner
    cdef int column
    for column in range(2):
        side = sides[e, column]
        face, corner = side // 3, side % 3
        l0, l1, l2 = lengths[face_edges[face, 0]], lengths[face_edges[face, 1]], lengths[face_edges[face, 2]]
        s0, s1, s2 = l0 * l0, l1 * l1, l2 * l2
        opposite = s0 if corner == 0 else (s1 if corner == 1 else s2)
        total += (s0 + s1 + s2 - 2.0 * opposite) / (8.0 * _heron_scalar(l0, l1, l2))
    return total


cdef Py_ssize_t _choose(const int64_t[::1] candidate, const double[::1] weight, Py_ssize_t n_candidates,
                        const int64_t[:, :] sides, double[::1] best_weight, int64_t[::1] best_edge,
                        uint8_t[::1] chosen) noexcept nogil:
    """The independent set of a round: a candidate edge is chosen when it holds the smallest
    (weight, edge id) in both its triangles; returns how many were chosen."""
    cdef Py_ssize_t i, count = 0
    cdef int64_t e, f, f0, f1
    cdef double w
    cdef int k
    for i in range(n_candidates):
        e, w = candidate[i], weight[i]
        for k in range(2):
            f = sides[e, k] // 3
            if w < best_weight[f] or (w == best_weight[f] and e < best_edge[f]):
                best_weight[f], best_edge[f] = w, e
    for i in range(n_candidates):
        e = candidate[i]
        f0, f1 = sides[e, 0] // 3, sides[e, 1] // 3
        chosen[i] = best_edge[f0] == e and best_edge[f1] == e and f0 != f1
        count += chosen[i]
    for i in range(n_candidates):
        e = candidate[i]
        for k in range(2):
            f = sides[e, k] // 3
            best_weight[f], best_edge[f] = INFINITY, -1
    return count


cdef void _flip_edge(int64_t e, int64_t[:, :] faces, int64_t[:, :] face_edges, int64_t[:, :] sides,
                     double[:] lengths, int64_t[5] touched) noexcept nogil:
    """Flip the interior edge ``e`` (``intrinsic_delaunay._flip`` for one edge) and write the
    five edges of its quad to ``touched``."""
    cdef int64_t h1 = sides[e, 0], h2 = sides[e, 1]
    cdef int64_t f = h1 // 3, a = h1 % 3, g = h2 // 3, b = h2 % 3
    cdef int64_t x = faces[f, a], p = faces[f, ((a + 1) % 3)], q = faces[f, ((a + 2) % 3)], y = faces[g, b]
    cdef int64_t e_xq = face_edges[f, ((a + 1) % 3)], e_xp = face_edges[f, ((a + 2) % 3)]
    cdef int64_t e_py = face_edges[g, ((b + 1) % 3)], e_yq = face_edges[g, ((b + 2) % 3)]
    cdef double l_pq = lengths[e], l_xp = lengths[e_xp], l_xq = lengths[e_xq], l_py = lengths[e_py], l_yq = lengths[e_yq]
    cdef double area_f = _heron_scalar(l_pq, l_xq, l_xp), area_g = _heron_scalar(l_pq, l_yq, l_py)
    cdef double cos_f = (l_xp * l_xp + l_pq * l_pq - l_xq * l_xq) / (2 * l_xp * l_pq)
    cdef double cos_g = (l_py * l_py + l_pq * l_pq - l_yq * l_yq) / (2 * l_py * l_pq)
    cdef double sin_f = 2 * area_f / (l_xp * l_pq), sin_g = 2 * area_g / (l_py * l_pq)
    cdef double cos_sum = cos_f * cos_g - sin_f * sin_g
    cdef double new_length = sqrt(_larger(l_xp * l_xp + l_py * l_py - 2 * l_xp * l_py * cos_sum, 0.0))
    cdef int64_t outer[4]
    cdef int64_t old_side[4]
    cdef int64_t new_side[4]
    cdef int64_t column[4]
    cdef int k
    outer[0], old_side[0], new_side[0] = e_py, 3 * g + ((b + 1) % 3), 3 * f + 0
    outer[1], old_side[1], new_side[1] = e_xp, 3 * f + ((a + 2) % 3), 3 * f + 2
    outer[2], old_side[2], new_side[2] = e_xq, 3 * f + ((a + 1) % 3), 3 * g + 0
    outer[3], old_side[3], new_side[3] = e_yq, 3 * g + ((b + 2) % 3), 3 * g + 2
    for k in range(4):  # read every column before writing any (as the vectorized flip)
        column[k] = 0 if sides[outer[k], 0] == old_side[k] else 1
    faces[f, 0], faces[f, 1], faces[f, 2] = x, p, y
    faces[g, 0], faces[g, 1], faces[g, 2] = y, q, x
    face_edges[f, 0], face_edges[f, 1], face_edges[f, 2] = e_py, e, e_xp
    face_edges[g, 0], face_edges[g, 1], face_edges[g, 2] = e_xq, e, e_yq
    for k in range(4):
        sides[outer[k], column[k]] = new_side[k]
    sides[e, 0] = 3 * f + 1
    sides[e, 1] = 3 * g + 1
    lengths[e] = new_length
    touched[0], touched[1], touched[2], touched[3], touched[4] = e, e_xp, e_xq, e_py, e_yq


def flip_rounds(int64_t[:, :] faces, int64_t[:, :] face_edges, int64_t[:, :] sides, double[:] lengths,
                double delaunay_tol, Py_ssize_t max_rounds):
    """Compiled twin of ``intrinsic_delaunay.flip_rounds_numpy``: the same rounds, the same
    independent sets (smallest (weight, edge id) in both triangles), the same flips in the same
    order, so the triangulation and the lengths agree bit for bit. Updates the arrays in place;
    returns (flips, rounds, finished)."""
    cdef Py_ssize_t n_edges = sides.shape[0], n_faces = faces.shape[0], e, i, n_check = 0, n_candidates, n_marked
    check_array = np.empty(n_edges, np.int64)
    candidate_array = np.empty(n_edges, np.int64)
    weight_array = np.empty(n_edges)
    chosen_array = np.zeros(n_edges, np.uint8)
    best_weight_array = np.full(n_faces, np.inf)
    best_edge_array = np.full(n_faces, -1, np.int64)
    mark_array = np.zeros(n_edges, np.uint8)
    marked_array = np.empty(n_edges, np.int64)
    cdef int64_t[::1] check = check_array, candidate = candidate_array, best_edge = best_edge_array
    cdef int64_t[::1] marked = marked_array
    cdef double[::1] weight = weight_array, best_weight = best_weight_array
    cdef uint8_t[::1] chosen = chosen_array, mark = mark_array
    cdef int64_t touched[5]
    cdef int64_t t
    cdef double w
    cdef Py_ssize_t flips = 0, rounds = 0
    cdef int k
    for e in range(n_edges):
        if sides[e, 1] >= 0:
            check[n_check] = e
            n_check += 1
    while n_check > 0:
        if rounds >= max_rounds:
            return flips, rounds, False
        n_candidates = 0
        for i in range(n_check):
            w = _edge_weight(check[i], sides, face_edges, lengths)
            if w < -delaunay_tol:
                candidate[n_candidates] = check[i]
                weight[n_candidates] = w
                n_candidates += 1
        if n_candidates == 0:
            break
        rounds += 1
        flips += _choose(candidate, weight, n_candidates, sides, best_weight, best_edge, chosen)
        n_marked = 0
        for i in range(n_candidates):
            if not chosen[i]:  # checked again next round
                t = candidate[i]
                if not mark[t]:
                    mark[t] = True
                    marked[n_marked] = t
                    n_marked += 1
                continue
            _flip_edge(candidate[i], faces, face_edges, sides, lengths, touched)
            for k in range(5):  # the quad's interior edges are checked next round
                t = touched[k]
                if sides[t, 1] >= 0 and not mark[t]:
                    mark[t] = True
                    marked[n_marked] = t
                    n_marked += 1
        check_array[:n_marked] = np.sort(marked_array[:n_marked])
        n_check = n_marked
        for i in range(n_marked):
            mark[marked[i]] = False
    return flips, rounds, True
