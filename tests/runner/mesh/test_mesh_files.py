"""decrun.runner.mesh.files.read: every bad file is one typed MeshError naming file, cause and
place; every good file reads exactly what it holds, in every format, and agrees with
pymeshlab wherever pymeshlab drops nothing."""

from __future__ import annotations

import struct
import time
from pathlib import Path

import meshio
import numpy as np
import pymeshlab
import pytest

from decrun.errors import (
    IndexOutOfRangeError,
    MeshError,
    NonFiniteCoordinateError,
    RepeatedVertexError,
)
from decrun.runner.mesh.files.read import read_mesh_file
from decrun.runner.mesh.files.text import TextTokens

SAMPLES = Path(pymeshlab.__file__).resolve().parent / "tests" / "sample_meshes"

# ------------------------------------------------------------------------------------
# small independent writers (the file formats by their specs, not by the reader)
# ------------------------------------------------------------------------------------

#: the surface of the unit tetrahedron, outward oriented
TET_V = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
TET_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def quad_grid(n: int = 3):
    """(n+1)² vertices of the unit square and n² quads (counter-clockwise)."""
    x, y = np.meshgrid(np.arange(n + 1) / n, np.arange(n + 1) / n, indexing="xy")
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="xy")
    a = (j * (n + 1) + i).ravel()
    return V, np.column_stack([a, a + 1, a + n + 2, a + n + 1])


def fan(polygons) -> np.ndarray:
    """Reference fan triangulation, polygon by polygon (tests only, tiny inputs)."""
    return np.array([[p[0], p[i], p[i + 1]] for p in polygons for i in range(1, len(p) - 1)])


def obj_text(V, faces, corner=lambda i, j: f"{i + 1}") -> bytes:
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(V, dtype=float).tolist()]
    lines += ["f " + " ".join(corner(int(i), j) for j, i in enumerate(f)) for f in faces]
    return ("\n".join(lines) + "\n").encode()


def off_text(V, faces) -> bytes:
    lines = ["OFF", f"{len(V)} {len(faces)} 0"] + [f"{x!r} {y!r} {z!r}" for x, y, z in np.asarray(V, dtype=float).tolist()]
    lines += [f"{len(f)} " + " ".join(str(int(i)) for i in f) for f in faces]
    return ("\n".join(lines) + "\n").encode()


def ply_bytes(V, faces, encoding="ascii", face_flags=False, vertex_type="double", flag=0) -> bytes:
    """PLY with a 'camera' element first, vertex (x y z + float quality), face (uchar/int list
    [+ int flags = ``flag``]) — the layout of pymeshlab's range maps."""
    header = ["ply", f"format {encoding} 1.0", "comment test", "element camera 1", "property float focal",
              f"element vertex {len(V)}", f"property {vertex_type} x", f"property {vertex_type} y",
              f"property {vertex_type} z", "property float quality",
              f"element face {len(faces)}", "property list uchar int vertex_indices"]
    header += ["property int flags"] if face_flags else []
    head = ("\n".join(header + ["end_header"]) + "\n").encode()
    if encoding == "ascii":
        body = ["35.5"] + [f"{x!r} {y!r} {z!r} 0.5" for x, y, z in np.asarray(V, dtype=float).tolist()]
        body += [f"{len(f)} " + " ".join(str(int(i)) for i in f) + (f" {flag}" if face_flags else "") for f in faces]
        return head + ("\n".join(body) + "\n").encode()
    order = "<" if encoding == "binary_little_endian" else ">"
    vt = "d" if vertex_type == "double" else "f"
    out = [struct.pack(order + "f", 35.5)]
    out += [struct.pack(order + vt * 3 + "f", *p, 0.5) for p in V]
    for f in faces:
        out.append(struct.pack(order + "B" + "i" * len(f), len(f), *map(int, f)))
        if face_flags:
            out.append(struct.pack(order + "i", flag))
    return head + b"".join(out)


def stl_ascii(V, F) -> bytes:
    lines = ["solid test"]
    for f in F:
        lines += ["  facet normal 0 0 0", "    outer loop"] + [f"      vertex {x!r} {y!r} {z!r}" for x, y, z in V[f].tolist()]
        lines += ["    endloop", "  endfacet"]
    return ("\n".join(lines + ["endsolid test"]) + "\n").encode()


def stl_binary(V, F) -> bytes:
    records = b"".join(struct.pack("<12fH", 0, 0, 0, *V[f].astype(np.float32).ravel(), 0) for f in F)
    return b"binary stl header".ljust(80, b" ") + struct.pack("<I", len(F)) + records


def write(tmp_path: Path, name: str, content: bytes) -> Path:
    path = tmp_path / name
    path.write_bytes(content)
    return path


def meshio_file(name, points, cells):
    def make(tmp_path: Path) -> Path:
        path = tmp_path / name
        meshio.write(str(path), meshio.Mesh(points, cells))
        return path
    return named(make, name)


def named(make, case_id: str):
    """A path maker (tmp_path -> Path) with the id its corpus case is shown under."""
    make.case_id = case_id
    return make


# ------------------------------------------------------------------------------------
# the corpus of bad inputs
# ------------------------------------------------------------------------------------

V3 = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
OFF_HEAD = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n"
PLY_HEAD = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n")
STL_FACET = "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n"
BAD = [
    # OBJ -------------------------------------------------------------------------
    ("index0.obj", V3 + "f 0 1 2\n", IndexOutOfRangeError, ["line 4: face 0 references vertex 0 (OBJ indices start at 1)"]),
    ("high.obj", V3 + "f 1 2 3\nf 1 2 4\n", IndexOutOfRangeError, ["line 5: face 1 references vertex 4", "defines 3"]),
    ("negative.obj", V3 + "f -1 -2 -4\n", IndexOutOfRangeError, ["line 4: face 0 references vertex -4 (relative)", "only 3"]),
    ("negative_early.obj", "v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n", IndexOutOfRangeError, ["line 3", "vertex -3", "only 2 vertices are defined before"]),
    ("repeat.obj", V3 + "v 1 1 0\nf 2 2 3\n", RepeatedVertexError, ["line 5: face 0 [1, 1, 2] lists vertex 1 twice"]),
    ("repeat_quad.obj", V3 + "v 1 1 0\nf 1 2 3 1\n", RepeatedVertexError, ["line 5: face 0", "lists vertex 0 twice"]),
    ("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", NonFiniteCoordinateError, ["line 2: vertex 1 has a non-finite coordinate"]),
    ("inf.obj", "v 0 0 0\nv 1 0 0\nv 0 -inf 0\nf 1 2 3\n", NonFiniteCoordinateError, ["line 3: vertex 2"]),
    ("overflow_literal.obj", "v 1e400 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", NonFiniteCoordinateError, ["line 1: vertex 0"]),
    ("huge.obj", "v 0 0 0\nv 1e200 0 0\nv 0 1 0\nf 1 2 3\n", MeshError, ["line 2: vertex 1", "squared lengths would overflow"]),
    ("no_faces.obj", V3, MeshError, ["holds 3 vertices and no faces"]),
    ("empty.obj", "", MeshError, ["the file is empty"]),
    ("comments.obj", "# nothing here\n\n", MeshError, ["holds no vertices"]),
    ("binary.obj", b"\x00\x01\x02garbage\xff" * 10, MeshError, ["binary content at byte 0"]),
    ("words.obj", "hello world\n", MeshError, ["line 1: unknown OBJ statement 'hello'"]),
    ("two_corners.obj", V3 + "f 1 2\n", MeshError, ["line 4: face 0 has 2 corners"]),
    ("bad_number.obj", "v 0 x 0\n", MeshError, ["line 1: vertex coordinate 'x' is not a number"]),
    ("underscore.obj", "v 1_0 0 0\n", MeshError, ["line 1: vertex coordinate '1_0' is not a number"]),
    ("float_index.obj", V3 + "f 1.5 2 3\n", MeshError, ["line 4: vertex index '1.5' is not an integer"]),
    ("short_vertex.obj", "v 0 0\n", MeshError, ["line 1: vertex 0 has 2 values"]),
    ("vt_range.obj", V3 + "vt 0 0\nf 1/1 2/5 3/1\n", IndexOutOfRangeError, ["line 5: face 0 references texture coordinate 5"]),
    ("vn_zero.obj", V3 + "vn 0 0 1\nf 1//1 2//0 3//1\n", IndexOutOfRangeError, ["line 5: face 0 references normal 0 (OBJ indices start at 1)"]),
    ("slashes.obj", V3 + "f 1/1/1/1 2 3\n", MeshError, ["line 4: face 0 corner '1/1/1/1' has more than two '/'"]),
    ("empty_index.obj", V3 + "f 1/ 2/ 3/\n", MeshError, ["line 4: face 0 corner '1/' has an empty index"]),
    ("freeform.obj", V3 + "cstype bspline\n", MeshError, ["line 4: free-form geometry ('cstype')"]),
    ("continuation.obj", V3 + "f 1 2 \\\n3\n", MeshError, ["line 4: line continuation"]),
    ("weight.obj", "v 0 0 0 0.5\n", MeshError, ["line 1: vertex 0 has weight w=0.5"]),
    # OFF -------------------------------------------------------------------------
    ("range.off", OFF_HEAD + "3 0 1 3\n", IndexOutOfRangeError, ["line 6: face 0 references vertex 3", "the file has 3 vertices"]),
    ("repeat.off", OFF_HEAD + "3 0 1 1\n", RepeatedVertexError, ["line 6: face 0 [0, 1, 1] lists vertex 1 twice"]),
    ("nan.off", "OFF\n3 1 0\n0 0 0\nNaN 0 0\n0 1 0\n3 0 1 2\n", NonFiniteCoordinateError, ["line 4: vertex 1"]),
    ("short.off", "OFF\n4 1 0\n0 0 0\n1 0 0\n", MeshError, ["announces 4 vertices but the file ends after 2"]),
    ("extra.off", OFF_HEAD + "3 0 1 2\n3 0 2 1\n", MeshError, ["line 7: unexpected content '3 0 2 1'"]),
    ("not.off", "ply\nformat ascii 1.0\n", MeshError, ["line 1: not an OFF file"]),
    ("variant.off", "4OFF\n3 1 0\n", MeshError, ["OFF variant '4OFF' is not supported"]),
    ("noff.off", "NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0\n0 1 0 0 0 1\n3 0 1 2\n", MeshError, ["line 4: vertex 1 should have 6 values"]),
    ("count.off", OFF_HEAD + "4 0 1 2\n", MeshError, ["line 6: face 0 should be 'k i_1 ... i_k [colour]'"]),
    ("no_faces.off", "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n", MeshError, ["holds 3 vertices and no faces"]),
    ("zeros.off", bytes(64), MeshError, ["not a text file: binary content at byte 0"]),
    # PLY -------------------------------------------------------------------------
    ("range.ply", PLY_HEAD + "3 0 1 5\n", IndexOutOfRangeError, ["line 13: face 0 references vertex 5"]),
    ("too_many.ply", PLY_HEAD + "3 0 1 2 9\n", MeshError, ["line 13: face 0 has too many values"]),
    ("binary_body.ply", PLY_HEAD.encode() + b"3 0 1\x002\n", MeshError, ["not a text file: binary content at byte 177"]),
    ("garbage.ply", b"\x89PNG\r\n\x1a\n" + bytes(100), MeshError, ["not a PLY file: the first line is not 'ply'"]),
    ("no_end.ply", "ply\nformat ascii 1.0\nelement vertex 0\n", MeshError, ["no 'end_header' line"]),
    ("format.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n", MeshError, ["line 2: unsupported PLY format"]),
    ("no_z.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n",
     MeshError, ["line 3: the 'vertex' element has no scalar property 'z'"]),
    ("truncated.ply", ply_bytes(TET_V, TET_F, "binary_little_endian")[:-6], MeshError, ["ends inside element 'face'"]),
    ("huge_count.ply", ply_bytes(TET_V, TET_F, "binary_little_endian").replace(b"element face 4", b"element face 99999999999999"),
     MeshError, ["99999999999999 records declared"]),
    ("trailing.ply", ply_bytes(TET_V, TET_F, "binary_little_endian") + b"\0\0", MeshError, ["2 bytes follow the last element ('face')"]),
    ("range_binary.ply", ply_bytes(TET_V, [[0, 1, 2], [0, 1, 9]], "binary_big_endian"), IndexOutOfRangeError, ["face 1 references vertex 9"]),
    ("nan_binary.ply", ply_bytes(np.array([[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]]), [[0, 1, 2]], "binary_little_endian"),
     NonFiniteCoordinateError, ["vertex 1 has a non-finite coordinate"]),
    ("huge_binary.ply", ply_bytes(np.array([[0, 0, 0], [0, 0, -3e300], [0, 1, 0]]), [[0, 1, 2]], "binary_little_endian"),
     MeshError, ["vertex 1 has coordinate", "squared lengths would overflow"]),
    ("two_corners.ply", ply_bytes(TET_V, [[0, 1, 2], [0, 1]], "binary_little_endian", face_flags=True), MeshError, ["face 1 has 2 corners"]),
    # STL -------------------------------------------------------------------------
    ("garbage.stl", b"\x13\x37" * 100, MeshError, ["not an STL file", "size 200 bytes"]),
    ("structure.stl", "solid x\n" + STL_FACET.replace("endloop\n", "") + "endsolid x\n", MeshError, ["line 7: expected 'endloop', got 'endfacet'"]),
    ("normal.stl", "solid x\n" + STL_FACET.replace("normal 0 0 1", "normal 0 zero 1") + "endsolid x\n", MeshError,
     ["line 2: facet normal component 'zero' is not a number"]),
    ("degenerate.stl", stl_ascii(TET_V, np.array([[0, 1, 1]])), RepeatedVertexError, ["line 2: face 0", "lists vertex 1 twice"]),
    ("nan.stl", stl_binary(np.array([[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]])), NonFiniteCoordinateError, ["facet 0 corner 1"]),
    # meshio formats -------------------------------------------------------------
    (meshio_file("mixed.vtu", TET_V, [("triangle", TET_F), ("tetra", np.array([[0, 1, 2, 3]]))]), None, MeshError,
     ["mixes 4 faces with 1 tetrahedra"]),
    (meshio_file("lines.vtk", TET_V, [("line", np.array([[0, 1], [1, 2]]))]), None, MeshError, ["cells decrun cannot use (2 line)"]),
    (meshio_file("range.vtu", TET_V, [("tetra", np.array([[0, 1, 2, 3], [0, 1, 2, 4]]))]), None, IndexOutOfRangeError,
     ["tetrahedron 1 references vertex 4"]),
    (meshio_file("repeat.vtu", TET_V, [("tetra", np.array([[0, 1, 2, 2]]))]), None, RepeatedVertexError, ["tetrahedron 0 [0, 1, 2, 2] lists vertex 2 twice"]),
    ("garbage.msh", b"this is not gmsh\n", MeshError, ["meshio cannot read it"]),
    # paths ----------------------------------------------------------------------
    (named(lambda tmp: tmp / "missing.obj", "missing_path"), None, MeshError, ["file not found"]),
    (named(lambda tmp: tmp, "directory"), None, MeshError, ["is a directory"]),
    ("points.xyz", "0 0 0\n", MeshError, ["unsupported file extension '.xyz'", ".obj", ".ply", ".vtu"]),
    ("README", "v 0 0 0\n", MeshError, ["unsupported file extension '(none)'"]),
]


def _case_id(case) -> str:
    return case[0] if isinstance(case[0], str) else case[0].case_id


@pytest.mark.parametrize("source, content, error, fragments", BAD, ids=[_case_id(c) for c in BAD])
def test_bad_file_is_one_typed_error_naming_file_cause_and_place(tmp_path, source, content, error, fragments):
    if isinstance(source, str):
        path = write(tmp_path, source, content.encode() if isinstance(content, str) else content)
    else:
        path = source(tmp_path)
    with pytest.raises(MeshError) as caught:
        read_mesh_file(path)
    assert type(caught.value) is error, caught.value
    message = str(caught.value)
    assert message.startswith(f"mesh.path={str(path)!r}: "), message
    for fragment in fragments:
        assert fragment in message, message


def test_corpus_has_at_least_30_distinct_bad_inputs():
    assert len(BAD) >= 30 and len({_case_id(c) for c in BAD}) == len(BAD)


def test_error_names_the_config_key(tmp_path):
    path = write(tmp_path, "fin.obj", (V3 + "f 0 1 2\n").encode())
    with pytest.raises(IndexOutOfRangeError, match=r"^mesh.sample='.*fin.obj': line 4: face 0 references vertex 0"):
        read_mesh_file(path, key="mesh.sample")


# ------------------------------------------------------------------------------------
# good inputs: exact content in every format
# ------------------------------------------------------------------------------------

TET_SURFACE = {
    "obj": lambda: obj_text(TET_V, TET_F),
    "off": lambda: off_text(TET_V, TET_F),
    "ply": lambda: ply_bytes(TET_V, TET_F, "ascii"),
    "ply_le": lambda: ply_bytes(TET_V, TET_F, "binary_little_endian", face_flags=True),
    "ply_be": lambda: ply_bytes(TET_V, TET_F, "binary_big_endian", vertex_type="float"),
}


@pytest.mark.parametrize("kind", sorted(TET_SURFACE))
def test_tetrahedron_surface_reads_exactly_and_as_pymeshlab_loads_it(tmp_path, kind):
    path = write(tmp_path, f"tet.{kind.split('_')[0]}", TET_SURFACE[kind]())
    mesh = read_mesh_file(path)
    assert np.array_equal(mesh.vertices, TET_V) and np.array_equal(mesh.cells, TET_F)
    assert mesh.counts["vertices"] == 4 and mesh.counts["faces"] == 4 and mesh.counts["triangulated_faces"] == 0
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(path))
    loaded = ms.current_mesh()
    assert np.array_equal(loaded.vertex_matrix(), mesh.vertices)
    assert np.array_equal(loaded.face_matrix(), mesh.cells)


def test_text_format_variants_read_the_same_mesh(tmp_path):
    """CRLF line ends, a UTF-8 byte order mark, comments, OFF counts on the keyword line or with no keyword, OFF face
    colours, PLY comment/obj_info lines: all the same tetrahedron."""
    variants = {
        "crlf.obj": obj_text(TET_V, TET_F).replace(b"\n", b"\r\n"),
        "bom.obj": b"\xef\xbb\xbf" + obj_text(TET_V, TET_F),
        "comments.obj": b"# header\n" + obj_text(TET_V, TET_F).replace(b"\nf", b" # trailing\n\n  f") + b"# end",
        "inline.off": b"OFF 4 4 6\n# comment\n" + b"\n".join(off_text(TET_V, TET_F).split(b"\n")[2:]),
        "bare.off": b"\n".join(off_text(TET_V, TET_F).split(b"\n")[1:]),
        "noff.off": off_text(TET_V, TET_F).replace(b"OFF", b"NOFF").replace(b".0\n", b".0 0 0 1\n"),
        "cnoff.off": off_text(TET_V, TET_F).replace(b"OFF", b"CNOFF").replace(b".0\n", b".0 0 0 1 255 0 0 255\n"),
        "colours.off": b"\n".join(line + (b" 0.5 0.5 0.5 1" if line.startswith(b"3 ") else b"")
                                   for line in off_text(TET_V, TET_F).split(b"\n")),
        "crlf.ply": ply_bytes(TET_V, TET_F).replace(b"\n", b"\r\n").replace(b"comment test", b"obj_info x\r\ncomment y"),
    }
    for name, content in variants.items():
        mesh = read_mesh_file(write(tmp_path, name, content))
        assert np.array_equal(mesh.vertices, TET_V) and np.array_equal(mesh.cells, TET_F), name


PYMESHLAB_WRITES = [("obj", {}), ("obj", {"save_vertex_normal": False}), ("off", {}), ("off", {"save_vertex_normal": False}),
                    ("ply", {}), ("ply", {"binary": False}), ("ply", {"save_vertex_normal": False}), ("stl", {}), ("stl", {"binary": False})]


@pytest.mark.parametrize("ext, options", PYMESHLAB_WRITES, ids=[f"{e}-{'-'.join(o) or 'default'}" for e, o in PYMESHLAB_WRITES])
def test_files_pymeshlab_writes_read_back_as_pymeshlab_loads_them(tmp_path, ext, options):
    """pymeshlab's own writers (full-precision floats, NOFF, vn lines, binary PLY/STL)."""
    ms = pymeshlab.MeshSet()
    ms.create_torus(hsubdiv=12, vsubdiv=8)
    path = tmp_path / f"torus.{ext}"
    ms.save_current_mesh(str(path), **options)
    mesh = read_mesh_file(path)
    loaded = pymeshlab.MeshSet()
    loaded.load_new_mesh(str(path))
    V, F = loaded.current_mesh().vertex_matrix(), loaded.current_mesh().face_matrix()
    assert np.array_equal(mesh.cells, F)
    if ext == "stl":  # VCG parses ASCII STL into float32; decrun keeps the decimal exactly
        assert np.array_equal(mesh.vertices.astype(np.float32), V.astype(np.float32))
    else:
        assert np.array_equal(mesh.vertices, V)


@pytest.mark.parametrize("writer", [stl_ascii, stl_binary])
def test_stl_corners_merge_into_the_shared_vertices_in_first_appearance_order(tmp_path, writer):
    path = write(tmp_path, "tet.stl", writer(TET_V, TET_F))
    mesh = read_mesh_file(path)
    order = np.unique(TET_F.ravel(), return_index=True)[1].argsort()  # vertices by first corner
    first_seen = np.unique(TET_F.ravel())[order]
    rank = np.argsort(first_seen)
    assert np.array_equal(mesh.vertices, TET_V[first_seen])
    assert np.array_equal(mesh.cells, rank[TET_F])
    assert mesh.format == ("stl-ascii" if writer is stl_ascii else "stl-binary")


@pytest.mark.parametrize("ext", ["vtu", "vtk", "msh", "mesh"])
def test_tet_mesh_written_with_meshio_reads_back_exactly(tmp_path, ext):
    rng = np.random.default_rng(3)
    points = rng.random((30, 3))
    import scipy.spatial

    tets = scipy.spatial.Delaunay(points).simplices.astype(np.int64)
    path = tmp_path / f"cloud.{ext}"
    meshio.write(str(path), meshio.Mesh(points, [("tetra", tets)]))
    mesh = read_mesh_file(path)
    assert mesh.is_volume and mesh.format == f"meshio-{ext}"
    assert np.array_equal(mesh.vertices, points) and np.array_equal(mesh.cells, tets)
    assert mesh.counts["tetrahedra"] == len(tets) == mesh.counts["cells"]


def test_quad_mesh_is_fan_triangulated_and_counted_in_every_format(tmp_path):
    V, Q = quad_grid(3)
    expected = fan(Q)
    files = {
        "grid.obj": obj_text(V, Q), "grid.off": off_text(V, Q), "grid.ply": ply_bytes(V, Q),
        "grid_bin.ply": ply_bytes(V, Q, "binary_little_endian", face_flags=True),
    }
    for name, content in files.items():
        path = write(tmp_path, name, content)
        mesh = read_mesh_file(path)
        assert np.array_equal(mesh.cells, expected), name
        assert mesh.counts["triangulated_faces"] == 9 and mesh.counts["cells"] == 18, name
        assert np.array_equal(mesh.cell_face, np.repeat(np.arange(9), 2)), name
        ms = pymeshlab.MeshSet()
        ms.load_new_mesh(str(path))
        assert np.array_equal(ms.current_mesh().face_matrix(), expected), name  # pymeshlab fans the same way
    vtu = meshio_file("grid.vtu", V, [("quad", Q)])(tmp_path)
    mesh = read_mesh_file(vtu)
    assert np.array_equal(mesh.vertices, V) and np.array_equal(mesh.cells, expected)
    assert mesh.counts["quad"] == 9 and mesh.counts["triangulated_faces"] == 9


def test_binary_ply_with_mixed_polygon_sizes_matches_the_ascii_file(tmp_path):
    """Variable-size binary records (sizes 3..7, a property after the list) go through the
    pointer-doubling record finder; the ASCII twin is parsed line by line."""
    rng = np.random.default_rng(0)
    V = rng.random((40, 3))
    polygons = [rng.choice(40, size=int(k), replace=False) for k in rng.integers(3, 8, size=57)]
    ascii_mesh = read_mesh_file(write(tmp_path, "a.ply", ply_bytes(V, polygons, "ascii", face_flags=True)))
    for encoding in ("binary_little_endian", "binary_big_endian"):
        binary = read_mesh_file(write(tmp_path, f"{encoding}.ply", ply_bytes(V, polygons, encoding, face_flags=True)))
        assert np.array_equal(binary.vertices, V) and np.array_equal(binary.cells, ascii_mesh.cells)
    assert np.array_equal(ascii_mesh.cells, fan(polygons))
    assert ascii_mesh.counts["triangulated_faces"] == sum(len(p) > 3 for p in polygons)
    assert ascii_mesh.counts["camera"] == 1


def test_ply_faces_with_two_lists_and_a_scalar_read_in_both_encodings(tmp_path):
    """Record layout 'ushort list of uint indices, uchar list of float texcoords, uchar
    material' with varying lengths: the record walker steps over every property."""
    rng = np.random.default_rng(1)
    V = rng.random((12, 3))
    polygons = [rng.choice(12, size=int(k), replace=False) for k in rng.integers(3, 6, size=20)]
    header = ("ply\nformat {} 1.0\nelement vertex 12\nproperty double x\nproperty double y\nproperty double z\n"
              "element face 20\nproperty list ushort uint vertex_indices\nproperty list uchar float texcoord\n"
              "property uchar material\nend_header\n")
    ascii_body = "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in V.tolist())
    ascii_body += "".join(f"{len(p)} {' '.join(map(str, p))} {2 * len(p)} {' '.join(['0.5'] * 2 * len(p))} 3\n" for p in polygons)
    binary_body = V.astype("<f8").tobytes() + b"".join(
        struct.pack(f"<H{len(p)}IB{2 * len(p)}fB", len(p), *map(int, p), 2 * len(p), *[0.5] * (2 * len(p)), 3) for p in polygons
    )
    as_text = read_mesh_file(write(tmp_path, "t.ply", (header.format("ascii") + ascii_body).encode()))
    as_binary = read_mesh_file(write(tmp_path, "b.ply", header.format("binary_little_endian").encode() + binary_body))
    for mesh in (as_text, as_binary):
        assert np.array_equal(mesh.vertices, V) and np.array_equal(mesh.cells, fan(polygons))


def test_obj_index_forms_all_give_the_same_mesh(tmp_path):
    """1-based, negative-relative and v/vt/vn corners of one mesh read identically."""
    V, Q = quad_grid(2)
    n = len(V)
    texture = "".join(f"vt {u} 0\n" for u in range(n)).encode()
    normals = "".join("vn 0 0 1\n" for _ in range(n)).encode()
    forms = {
        "plain": obj_text(V, Q),
        "negative": obj_text(V, Q, lambda i, j: f"{i - n}"),
        "v_vt": texture + obj_text(V, Q, lambda i, j: f"{i + 1}/{i + 1}"),
        "v_vn": normals + obj_text(V, Q, lambda i, j: f"{i + 1}//{n - i}"),
        "v_vt_vn": texture + normals + obj_text(V, Q, lambda i, j: f"{i - n}/{i + 1}/-{j + 1}"),
    }
    meshes = {k: read_mesh_file(write(tmp_path, f"{k}.obj", c)) for k, c in forms.items()}
    for name, mesh in meshes.items():
        assert np.array_equal(mesh.vertices, V) and np.array_equal(mesh.cells, fan(Q)), name
    assert meshes["v_vt_vn"].counts["texture_coordinates"] == n == meshes["v_vt_vn"].counts["normals"]
    # line numbers point at the face statements
    assert np.array_equal(meshes["plain"].face_line, np.arange(len(Q)) + n + 1)


@pytest.mark.parametrize("name", sorted(str(p.relative_to(SAMPLES)) for p in SAMPLES.rglob("*") if p.suffix in (".obj", ".ply", ".off", ".stl")))
def test_every_pymeshlab_sample_reads_and_equals_what_pymeshlab_loads(name):
    mesh = read_mesh_file(SAMPLES / name)
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(SAMPLES / name))
    loaded = ms.current_mesh()
    assert mesh.counts["vertices"] == loaded.vertex_number() == len(mesh.vertices)
    assert mesh.counts["cells"] == loaded.face_number() == len(mesh.cells)
    assert np.array_equal(loaded.vertex_matrix(), mesh.vertices)
    assert np.array_equal(loaded.face_matrix(), mesh.cells)


# ------------------------------------------------------------------------------------
# what pymeshlab drops silently, decrun reads or refuses
# ------------------------------------------------------------------------------------


def test_pymeshlab_silently_drops_a_nan_vertex_and_decrun_refuses_the_file(tmp_path):
    """What decrun's own readers exist for: pymeshlab loads 3 of 4 vertices and 1 of 2 faces
    of this OBJ without a word; read_mesh_file refuses the file, naming the line."""
    path = write(tmp_path, "nan.obj", b"v 0 0 0\nv nan 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n")
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(path))
    loaded = ms.current_mesh()
    assert (loaded.vertex_number(), loaded.face_number()) == (3, 1)
    with pytest.raises(NonFiniteCoordinateError, match=r"line 2: vertex 1"):
        read_mesh_file(path)


def test_pymeshlab_drops_ply_faces_whose_flags_mark_them_deleted_and_decrun_reads_them(tmp_path):
    """A PLY face property named 'flags' is read by VCG as its own bit field; bit 0 means
    'deleted', so pymeshlab silently loads none of these faces. decrun reads all four."""
    path = write(tmp_path, "flags.ply", ply_bytes(TET_V, TET_F, "binary_little_endian", face_flags=True, flag=1))
    mesh = read_mesh_file(path)
    assert np.array_equal(mesh.cells, TET_F)
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(path))
    loaded = ms.current_mesh()
    assert loaded.face_number() == 0


# ------------------------------------------------------------------------------------
# the number parser: the fast integer path equals Python's float()/int() exactly
# ------------------------------------------------------------------------------------


def test_fast_decimal_parser_equals_python_float_and_int_bit_for_bit():
    rng = np.random.default_rng(7)
    values = rng.standard_normal(5000) * 10.0 ** rng.integers(-9, 9, 5000)
    tokens = [f"{v:.{p}f}" for v, p in zip(values, rng.integers(0, 14, 5000), strict=True)]
    tokens += ["-0.0", "0", ".5", "5.", "+1.25", "-.5", "123456789012345", "1234567890123456", "1e5",
               "-2.5E-3", "nan", "-inf", "00012.5000", "0.1", "0.30000000000000004"]
    text = TextTokens(" ".join(tokens).encode(), "w")
    ours = text.token_numbers(np.arange(len(tokens)), np.float64, "x")
    reference = np.array([float(t) for t in tokens])
    assert np.array_equal(ours.view(np.int64)[~np.isnan(ours)], reference.view(np.int64)[~np.isnan(reference)])
    integers = [str(i) for i in rng.integers(-10**15, 10**15, 5000)] + ["+5", "-0", "007", "98765432109876543"]
    text = TextTokens("\n".join(integers).encode(), "w")
    assert np.array_equal(text.token_numbers(np.arange(len(integers)), np.int64, "i"), [int(i) for i in integers])


@pytest.mark.parametrize("token", ["-", ".", "1.2.3", "--1", "1-", "+", "0x10", "1e", "١٢"])
def test_malformed_numbers_are_rejected_with_their_line(token):
    text = TextTokens(f"\n\n{token}\n".encode(), "where")
    with pytest.raises(MeshError, match=r"^where: line 3: x '.*' is not a number$"):
        text.token_numbers([0], np.float64, "x")


@pytest.mark.slow
def test_reading_bunny_is_at_most_about_twice_pymeshlab_load():
    path = SAMPLES / "bunny.obj"
    ours, theirs = [], []
    for _ in range(5):
        start = time.perf_counter()
        read_mesh_file(path)
        ours.append(time.perf_counter() - start)
        ms = pymeshlab.MeshSet()
        start = time.perf_counter()
        ms.load_new_mesh(str(path))
        theirs.append(time.perf_counter() - start)
    assert min(ours) < 2.5 * min(theirs), (min(ours), min(theirs))


def test_damaged_files_fail_only_with_mesh_errors_that_name_the_file(tmp_path):
    """Seeded mutations (byte flips, cuts, deletions, inserted number-ish bytes) of good
    files in every format: reading either succeeds or raises MeshError naming the file —
    never an IndexError, ValueError, struct or numpy error from inside a reader."""
    V, Q = quad_grid(2)
    seeds = {
        "a.obj": obj_text(V, Q), "b.obj": obj_text(V, Q, lambda i, j: f"{i - len(V)}/{i + 1}/1"),
        "a.off": off_text(V, Q), "a.ply": ply_bytes(V, Q), "b.ply": ply_bytes(V, Q, "binary_little_endian", face_flags=True),
        "c.ply": ply_bytes(TET_V, TET_F, "binary_big_endian"), "a.stl": stl_ascii(TET_V, TET_F), "b.stl": stl_binary(TET_V, TET_F),
    }
    rng = np.random.default_rng(2024)
    alphabet = np.frombuffer(b" 0123456789-./\nfv#e", dtype=np.uint8)
    failures = 0
    for _ in range(60):
        for name, content in seeds.items():
            data = bytearray(content)
            at = int(rng.integers(len(data)))
            operation = int(rng.integers(4))
            if operation == 0:
                data[at] = int(rng.integers(256))
            elif operation == 1:
                data = data[:at]
            elif operation == 2:
                del data[at:at + int(rng.integers(1, 8))]
            else:
                data[at:at] = rng.choice(alphabet, int(rng.integers(1, 6))).tobytes()
            path = write(tmp_path, name, bytes(data))
            try:
                read_mesh_file(path)
            except MeshError as error:
                failures += 1
                assert str(error).startswith(f"mesh.path={str(path)!r}: "), error
    assert failures > 100  # the mutations do break most files
