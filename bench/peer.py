#!/usr/bin/python3
"""The two-step peer pipeline a user would otherwise chain to get a surface and its offset from an oriented
cloud, plus the small mesh utilities the fidelity benchmark shares with it.

  1. Open3D screened Poisson reconstruction (Debian package python3-open3d, module open3d) of the cloud;
  2. an exact distance-field offset of that mesh with OpenVDB (Debian package python3-openvdb, module
     pyopenvdb): the mesh is converted to a narrow-band signed distance grid wide enough to hold the offset,
     and the grid's (-delta)-isosurface is meshed. VDB level sets are negative inside, so an inward offset
     delta > 0 (duplexfit's convention) is the isovalue -delta, an outward one (delta < 0) is +|delta|.

Both peer packages are optional: they are imported only when a step needs them, and a missing one raises
PeerMissing naming the package to install. numpy is required.

Library use (bench/fidelity.py, bench/fit_bench.py):  read_cloud, read_mesh, write_mesh, poisson, vdb_offset,
two_step, components, sphere_mesh, torus_mesh.
Command line (each step prints one JSON object on stdout, so a caller can run it in its own process):

  peer.py check                                    versions of the peer packages (exit 3 if one is missing)
  peer.py poisson CLOUD -o OUT.ply [--depth 9] [--scale 1.1] [--linear-fit] [--trim Q] [--threads N]
  peer.py offset MESH --delta D -o OUT.ply [--voxel H] [--margin 3] [--adaptivity 0]
  peer.py two-step CLOUD --delta D -o OUTDIR [--depth 9] [--voxel H] [--margin 3]
                                                   the whole chain, timed per stage (bench/fit_bench.py)
  peer.py components MESH                          connected components and their areas
  peer.py truth sphere|torus -o OUT.ply --radius R | --R R --r r [--tol 1e-5]
"""
import argparse
import json
import math
import os
import sys
import time

try:
    import numpy as np
except ImportError:  # the Debian peer packages live in the system interpreter
    sys.exit("peer.py: numpy is missing in %s: install python3-numpy and run with /usr/bin/python3" % sys.executable)

OPEN3D_PACKAGE = "python3-open3d (Debian/Ubuntu: apt-get install python3-open3d; or pip install open3d)"
OPENVDB_PACKAGE = "python3-openvdb (Debian/Ubuntu: apt-get install python3-openvdb; module pyopenvdb)"

# Defaults of the peer pipeline (documented in docs/fidelity.md by the benchmark).
POISSON_DEPTH = 9        # octree depth: grid no finer than 2^9 = 512 cells across the reconstruction cube
POISSON_SCALE = 1.1      # reconstruction cube / bounding cube of the samples (Open3D's and PoissonRecon's default)
POISSON_LINEAR_FIT = False  # Open3D's default
VDB_VOXEL_MAX = 0.002    # voxel = min(VDB_VOXEL_MAX, |delta| / VDB_VOXELS_PER_DELTA) unless given
VDB_VOXELS_PER_DELTA = 10.0
VDB_MARGIN = 3           # narrow-band half width = ceil(|delta| / voxel) + margin voxels


class PeerMissing(RuntimeError):
    """A peer package could not be imported; the message says which one to install."""


def import_open3d():
    try:
        import open3d  # noqa: F401
        return open3d
    except Exception as e:  # ImportError, or a shared library that fails to load
        raise PeerMissing("cannot import open3d (%s: %s): install %s" % (type(e).__name__, e, OPEN3D_PACKAGE))


def import_openvdb():
    try:
        import pyopenvdb
        return pyopenvdb
    except Exception as e:
        raise PeerMissing("cannot import pyopenvdb (%s: %s): install %s" % (type(e).__name__, e, OPENVDB_PACKAGE))


def versions():
    """{'open3d': version, 'openvdb': version}; raises PeerMissing for the first missing package."""
    o3d = import_open3d()
    vdb = import_openvdb()
    v = getattr(vdb, "LIBRARY_VERSION", None)
    return {"open3d": getattr(o3d, "__version__", "?"),
            "openvdb": ".".join(str(x) for x in v) if isinstance(v, tuple) else str(v)}


# ------------------------------------------------------------------------------------------------- PLY

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def _read_ply(path):
    """Parses a PLY file (ascii or binary, either endianness). Returns {element: {property: array}}; a list
    property becomes a list of arrays, or a 2-D array when every list has the same length."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise ValueError("%s: not a PLY file" % path)
    body = data.index(b"\n", end) + 1
    fmt, elements = None, []
    for line in data[:end].decode("ascii", "replace").splitlines():
        t = line.split()
        if not t or t[0] in ("ply", "comment", "obj_info"):
            continue
        if t[0] == "format":
            fmt = t[1]
        elif t[0] == "element":
            elements.append((t[1], int(t[2]), []))
        elif t[0] == "property":
            if t[1] == "list":
                elements[-1][2].append((t[4], _PLY_TYPES[t[2]], _PLY_TYPES[t[3]]))
            else:
                elements[-1][2].append((t[2], _PLY_TYPES[t[1]], None))
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise ValueError("%s: unsupported PLY format %r" % (path, fmt))
    out = {}
    if fmt == "ascii":
        tokens = data[body:].split()
        pos = 0
        for name, count, props in elements:
            cols = {p[0]: [] for p in props}
            for _ in range(count):
                for pname, t, item in props:
                    if item is None:
                        cols[pname].append(float(tokens[pos]))
                        pos += 1
                    else:
                        n = int(tokens[pos])
                        cols[pname].append([float(x) for x in tokens[pos + 1:pos + 1 + n]])
                        pos += 1 + n
            out[name] = {}
            for pname, t, item in props:
                if item is None:
                    out[name][pname] = np.asarray(cols[pname], dtype=t)
                else:
                    lens = {len(x) for x in cols[pname]}
                    out[name][pname] = (np.asarray(cols[pname], dtype=item) if len(lens) == 1
                                        else [np.asarray(x, dtype=item) for x in cols[pname]])
        return out
    bo = "<" if fmt == "binary_little_endian" else ">"
    pos = body
    for name, count, props in elements:
        if all(p[2] is None for p in props):
            dt = np.dtype([(p[0], bo + p[1]) for p in props])
            arr = np.frombuffer(data, dt, count, pos)
            pos += dt.itemsize * count
            out[name] = {p[0]: arr[p[0]] for p in props}
            continue
        # Fast path: one list property whose lists all have the length of the first (triangle meshes).
        lists = [p for p in props if p[2] is not None]
        if len(lists) == 1 and count > 0:
            head = 0
            first_len = None
            for pname, t, item in props:
                if item is None:
                    head += np.dtype(t).itemsize
                else:
                    first_len = int(np.frombuffer(data, bo + t, 1, pos + head)[0])
                    break
            fields = []
            for pname, t, item in props:
                if item is None:
                    fields.append((pname, bo + t))
                else:
                    fields.append(("__n_" + pname, bo + t))
                    fields.append((pname, bo + item, (first_len,)))
            dt = np.dtype(fields)
            if pos + dt.itemsize * count <= len(data):
                arr = np.frombuffer(data, dt, count, pos)
                if np.all(arr["__n_" + lists[0][0]] == first_len):
                    pos += dt.itemsize * count
                    out[name] = {p[0]: arr[p[0]] for p in props}
                    continue
        cols = {p[0]: [] for p in props}
        for _ in range(count):
            for pname, t, item in props:
                if item is None:
                    v = np.frombuffer(data, bo + t, 1, pos)[0]
                    pos += np.dtype(t).itemsize
                    cols[pname].append(v)
                else:
                    n = int(np.frombuffer(data, bo + t, 1, pos)[0])
                    pos += np.dtype(t).itemsize
                    cols[pname].append(np.frombuffer(data, bo + item, n, pos))
                    pos += np.dtype(item).itemsize * n
        out[name] = {}
        for pname, t, item in props:
            out[name][pname] = np.asarray(cols[pname], dtype=t) if item is None else cols[pname]
    return out


def read_cloud(path):
    """Oriented cloud: (points, normals) as float64 (n, 3) arrays."""
    ply = _read_ply(path)
    v = ply["vertex"]
    p = np.stack([v["x"], v["y"], v["z"]], axis=1).astype(np.float64)
    if not all(k in v for k in ("nx", "ny", "nz")):
        raise ValueError("%s: the cloud has no normals (nx, ny, nz)" % path)
    n = np.stack([v["nx"], v["ny"], v["nz"]], axis=1).astype(np.float64)
    return p, n


def read_mesh(path):
    """Triangle mesh: (vertices float64 (n, 3), faces int64 (m, 3)); polygons are fanned into triangles."""
    ply = _read_ply(path)
    v = ply["vertex"]
    verts = np.stack([v["x"], v["y"], v["z"]], axis=1).astype(np.float64)
    face = ply.get("face", {})
    key = "vertex_indices" if "vertex_indices" in face else ("vertex_index" if "vertex_index" in face else None)
    if key is None:
        lists = [k for k, a in face.items() if isinstance(a, list) or (hasattr(a, "ndim") and a.ndim == 2)]
        if not lists:
            return verts, np.zeros((0, 3), np.int64)
        key = lists[0]
    f = face[key]
    if isinstance(f, list):
        tris = [np.stack([np.full(len(p) - 2, p[0]), p[1:-1], p[2:]], axis=1) for p in f if len(p) >= 3]
        faces = np.concatenate(tris).astype(np.int64) if tris else np.zeros((0, 3), np.int64)
    elif f.shape[1] == 3:
        faces = f.astype(np.int64)
    else:
        k = f.shape[1]
        faces = np.concatenate([f[:, [0, i, i + 1]] for i in range(1, k - 1)]).astype(np.int64)
    return verts, faces


def write_mesh(path, verts, faces):
    """Binary little-endian PLY: float x y z, faces list uchar int (the layout of the shared meshes)."""
    verts = np.ascontiguousarray(verts, dtype="<f4")
    faces = np.asarray(faces, dtype=np.int64)
    rec = np.empty(len(faces), dtype=np.dtype([("n", "u1"), ("i", "<i4", (3,))]))
    rec["n"] = 3
    rec["i"] = faces
    with open(path, "wb") as f:
        f.write(("ply\nformat binary_little_endian 1.0\ncomment written by duplexfit bench/peer.py\n"
                 "element vertex %d\nproperty float x\nproperty float y\nproperty float z\n"
                 "element face %d\nproperty list uchar int vertex_indices\nend_header\n"
                 % (len(verts), len(faces))).encode("ascii"))
        f.write(verts.tobytes())
        f.write(rec.tobytes())


# --------------------------------------------------------------------------------------- mesh analysis

def face_areas(verts, faces):
    if len(faces) == 0:
        return np.zeros(0)
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def signed_volume(verts, faces):
    if len(faces) == 0:
        return 0.0
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def _labels(n, edges):
    """Connected-component labels of a graph on n nodes given an (m, 2) edge array: union-find done
    data-parallel (hook the larger root of every edge that joins two trees onto the smaller one, then
    compress paths; repeat until no edge joins two trees)."""
    parent = np.arange(n, dtype=np.int64)
    if len(edges) == 0:
        return parent
    u, v = edges[:, 0], edges[:, 1]
    while True:
        ru, rv = parent[u], parent[v]
        diff = ru != rv
        if not diff.any():
            break
        lo, hi = np.minimum(ru[diff], rv[diff]), np.maximum(ru[diff], rv[diff])
        parent[hi] = lo  # conflicting writes are fine: any smaller root will do, no cycle can form
        while True:  # pointer jumping until every node points at a root
            nxt = parent[parent]
            if np.array_equal(nxt, parent):
                break
            parent = nxt
    return parent


def components(verts, faces, weld=True):
    """Connected components of a triangle mesh (faces sharing a vertex; with weld, vertices at identical
    positions are one vertex). Returns a list of {'faces', 'area', 'share'} sorted by area, largest first,
    share = area / total area."""
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) == 0:
        return []
    if weld:
        _, remap = np.unique(np.asarray(verts, dtype=np.float64), axis=0, return_inverse=True)
        f = remap.reshape(-1)[faces]
    else:
        f = faces
    used, f = np.unique(f, return_inverse=True)
    f = f.reshape(-1, 3)
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]]])
    lab = _labels(len(used), edges)[f[:, 0]]
    roots, comp = np.unique(lab, return_inverse=True)
    areas = np.bincount(comp, weights=face_areas(np.asarray(verts, np.float64), faces), minlength=len(roots))
    counts = np.bincount(comp, minlength=len(roots))
    # Euler characteristic V - E + F of each component (welded vertices, undirected edges): its genus is
    # (2 - chi) / 2 when it is a closed orientable surface.
    nv_comp = np.bincount(comp[np.unique(f.reshape(-1), return_index=True)[1] // 3], minlength=len(roots))
    und = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    ecomp = np.concatenate([comp, comp, comp])
    _, first = np.unique(und, axis=0, return_index=True)
    ne_comp = np.bincount(ecomp[first], minlength=len(roots))
    chi = nv_comp - ne_comp + counts
    total = float(areas.sum())
    order = np.argsort(-areas, kind="stable")
    return [{"faces": int(counts[i]), "area": float(areas[i]), "share": float(areas[i] / total) if total > 0 else 0.0,
             "euler": int(chi[i]), "genus": (2 - int(chi[i])) / 2.0}
            for i in order]


def component_summary(comps, significant=0.01, tiny=0.001):
    """Counts of all, significant (>= significant of the total area) and tiny (< tiny of it) components."""
    return {"components": len(comps),
            "significant": sum(1 for c in comps if c["share"] >= significant),
            "tiny": sum(1 for c in comps if c["share"] < tiny),
            # handles of the significant components (their genus summed; a tiny piece's is left out)
            "genus": sum(c["genus"] for c in comps if c["share"] >= significant),
            "area": float(sum(c["area"] for c in comps)),
            "shares": [round(c["share"], 6) for c in comps[:20]]}


# ----------------------------------------------------------------------------------- analytic truth

def _segments(radius, tol):
    """Segments of a regular polygon on a circle of this radius whose sagitta is at most tol."""
    return max(8, int(math.ceil(math.pi / math.acos(max(-1.0, 1.0 - tol / radius)))))


def sphere_mesh(radius, center=(0.0, 0.0, 0.0), tol=1e-5):
    """Icosphere whose chords deviate from the sphere by at most about tol; outward oriented."""
    t = (1.0 + 5 ** 0.5) / 2.0
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
                  [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], dtype=np.float64)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
                  [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
                  [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]], dtype=np.int64)

    def max_sagitta(v, f):
        e = np.linalg.norm(v[f[:, 0]] - v[f[:, 1]], axis=1).max() * radius
        return e * e / (8.0 * radius) * 1.34  # the triangle's centroid sits a bit deeper than an edge midpoint

    while max_sagitta(v, f) > tol:
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        uniq, inv = np.unique(e, axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        mid = v[uniq[:, 0]] + v[uniq[:, 1]]
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        m = len(f)
        a, b, c = f[:, 0], f[:, 1], f[:, 2]
        ab, bc, ca = len(v) + inv[:m], len(v) + inv[m:2 * m], len(v) + inv[2 * m:]
        v = np.concatenate([v, mid])
        f = np.concatenate([np.stack([a, ab, ca], 1), np.stack([b, bc, ab], 1), np.stack([c, ca, bc], 1),
                            np.stack([ab, bc, ca], 1)])
    verts = v * radius + np.asarray(center, dtype=np.float64)
    if signed_volume(verts, f) < 0:
        f = f[:, ::-1]
    return verts, f


def torus_mesh(R, r, center=(0.0, 0.0, 0.0), tol=1e-5):
    """Torus around the z axis (tube radius r, centre-line radius R), a (u, v) grid fine enough that chords
    deviate by at most about tol; outward oriented."""
    nu = _segments(R - r, tol / 2.0)
    nv = _segments(r, tol / 2.0)
    u = np.arange(nu) * (2.0 * math.pi / nu)
    w = np.arange(nv) * (2.0 * math.pi / nv)
    U, W = np.meshgrid(u, w, indexing="ij")
    rho = R + r * np.cos(W)
    verts = np.stack([rho * np.cos(U), rho * np.sin(U), r * np.sin(W)], axis=-1).reshape(-1, 3)
    verts += np.asarray(center, dtype=np.float64)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    i, j = i.reshape(-1), j.reshape(-1)
    a = i * nv + j
    b = ((i + 1) % nu) * nv + j
    c = ((i + 1) % nu) * nv + (j + 1) % nv
    d = i * nv + (j + 1) % nv
    f = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    if signed_volume(verts, f) < 0:
        f = f[:, ::-1]
    return verts, f


# ------------------------------------------------------------------------------------------ the peer

def poisson(points, normals, depth=POISSON_DEPTH, scale=POISSON_SCALE, linear_fit=POISSON_LINEAR_FIT,
            trim=0.0, threads=-1):
    """Open3D screened Poisson reconstruction. Returns (verts, faces, info); info['seconds'] is the time of
    the reconstruction call alone. trim > 0 removes the vertices whose Poisson density is below that
    quantile (Open3D's usual clean-up; it opens the mesh, so it is off by default)."""
    o3d = import_open3d()
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    pcd = o3d.geometry.PointCloud()
    pcd.points = o3d.utility.Vector3dVector(np.asarray(points, dtype=np.float64))
    pcd.normals = o3d.utility.Vector3dVector(np.asarray(normals, dtype=np.float64))
    t0 = time.perf_counter()
    try:
        mesh, dens = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
            pcd, depth=depth, scale=scale, linear_fit=linear_fit, n_threads=threads)
    except TypeError:  # Open3D before 0.13 has no n_threads
        mesh, dens = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
            pcd, depth=depth, scale=scale, linear_fit=linear_fit)
    seconds = time.perf_counter() - t0
    dens = np.asarray(dens)
    removed = 0
    if trim > 0.0 and len(dens):
        cut = np.quantile(dens, trim)
        drop = dens < cut
        removed = int(drop.sum())
        mesh.remove_vertices_by_mask(drop)
    verts = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.triangles, dtype=np.int64)
    flipped = signed_volume(verts, faces) < 0
    if flipped:
        faces = faces[:, ::-1].copy()
    info = {"seconds": seconds, "depth": depth, "scale": scale, "linear_fit": bool(linear_fit), "trim": trim,
            "trimmed_vertices": removed, "threads": threads, "vertices": int(len(verts)), "faces": int(len(faces)),
            "flipped": bool(flipped)}
    return verts, faces, info


def default_voxel(delta):
    return min(VDB_VOXEL_MAX, abs(delta) / VDB_VOXELS_PER_DELTA)


def vdb_offset(verts, faces, delta, voxel=None, margin=VDB_MARGIN, adaptivity=0.0):
    """Exact offset of a closed mesh at signed delta (positive = inward): the mesh's narrow-band signed
    distance grid (voxel size `voxel`, half width covering |delta| plus `margin` voxels) meshed at the
    isovalue -delta. Returns (verts, faces, info); quads are split into triangles, faces outward."""
    vdb = import_openvdb()
    if delta == 0:
        raise ValueError("vdb_offset: delta must be non-zero")
    h = float(voxel) if voxel else default_voxel(delta)
    half_width = int(math.ceil(abs(delta) / h)) + int(margin)
    t0 = time.perf_counter()
    grid = vdb.FloatGrid.createLevelSetFromPolygons(
        np.ascontiguousarray(verts, dtype=np.float32), triangles=np.ascontiguousarray(faces, dtype=np.int32),
        transform=vdb.createLinearTransform(voxelSize=h), halfWidth=half_width)
    t1 = time.perf_counter()
    pts, tris, quads = grid.convertToPolygons(isovalue=-float(delta), adaptivity=float(adaptivity))
    t2 = time.perf_counter()
    active = int(grid.activeVoxelCount())
    del grid
    pts = np.asarray(pts, dtype=np.float64)
    tris = np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    quads = np.asarray(quads, dtype=np.int64).reshape(-1, 4)
    f = np.concatenate([tris, quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    # A quad whose split triangle repeats an index (collapsed quad) contributes nothing.
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    flipped = signed_volume(pts, f) < 0
    if flipped:
        f = f[:, ::-1].copy()
    info = {"seconds": t2 - t0, "seconds_to_volume": t1 - t0, "seconds_to_mesh": t2 - t1, "voxel": h,
            "half_width_voxels": half_width, "isovalue": -float(delta), "adaptivity": float(adaptivity),
            "active_voxels": active, "vertices": int(len(pts)), "faces": int(len(f)), "flipped": bool(flipped)}
    return pts, f, info


def two_step(cloud_path, delta, outdir, depth=POISSON_DEPTH, voxel=None, margin=VDB_MARGIN, threads=-1):
    """The whole peer chain as a user would run it: read the cloud, Poisson, write the zero mesh, VDB offset
    of that mesh at delta, write the offset mesh (outdir/zero.ply, outdir/offset1.ply, duplexfit's names).
    Both packages are imported before the clock starts. Returns {'seconds': {'read', 'poisson',
    'write_zero', 'offset', 'write_offset', 'total'}, 'poisson': info, 'vdb': info, 'zero', 'offset'}."""
    import_open3d()
    import_openvdb()
    zero_path = os.path.join(outdir, "zero.ply")
    offset_path = os.path.join(outdir, "offset1.ply")
    t = [time.perf_counter()]
    pts, nrm = read_cloud(cloud_path)
    t.append(time.perf_counter())
    v, f, pinfo = poisson(pts, nrm, depth=depth, threads=threads)
    t.append(time.perf_counter())
    write_mesh(zero_path, v, f)
    t.append(time.perf_counter())
    ov, of, vinfo = vdb_offset(v, f, delta, voxel, margin)
    t.append(time.perf_counter())
    write_mesh(offset_path, ov, of)
    t.append(time.perf_counter())
    names = ("read", "poisson", "write_zero", "offset", "write_offset")
    seconds = {k: t[i + 1] - t[i] for i, k in enumerate(names)}
    seconds["total"] = t[-1] - t[0]
    return {"seconds": seconds, "points": int(len(pts)), "poisson": pinfo, "vdb": vinfo,
            "zero": zero_path, "offset": offset_path}


# ------------------------------------------------------------------------------------- command line

def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("check")
    q = sub.add_parser("poisson")
    q.add_argument("cloud")
    q.add_argument("-o", "--output", required=True)
    q.add_argument("--depth", type=int, default=POISSON_DEPTH)
    q.add_argument("--scale", type=float, default=POISSON_SCALE)
    q.add_argument("--linear-fit", action="store_true", default=POISSON_LINEAR_FIT)
    q.add_argument("--trim", type=float, default=0.0)
    q.add_argument("--threads", type=int, default=-1)
    q = sub.add_parser("offset")
    q.add_argument("mesh")
    q.add_argument("--delta", type=float, required=True)
    q.add_argument("-o", "--output", required=True)
    q.add_argument("--voxel", type=float, default=0.0)
    q.add_argument("--margin", type=int, default=VDB_MARGIN)
    q.add_argument("--adaptivity", type=float, default=0.0)
    q = sub.add_parser("two-step")
    q.add_argument("cloud")
    q.add_argument("--delta", type=float, required=True)
    q.add_argument("-o", "--outdir", required=True)
    q.add_argument("--depth", type=int, default=POISSON_DEPTH)
    q.add_argument("--voxel", type=float, default=0.0)
    q.add_argument("--margin", type=int, default=VDB_MARGIN)
    q.add_argument("--threads", type=int, default=-1)
    q = sub.add_parser("components")
    q.add_argument("mesh")
    q.add_argument("--no-weld", action="store_true")
    q = sub.add_parser("truth")
    q.add_argument("shape", choices=["sphere", "torus"])
    q.add_argument("-o", "--output", required=True)
    q.add_argument("--radius", type=float, default=0.5)
    q.add_argument("--R", type=float, default=0.35)
    q.add_argument("--r", type=float, default=0.15)
    q.add_argument("--tol", type=float, default=1e-5)
    a = p.parse_args(argv)
    try:
        if a.cmd == "check":
            out = versions()
        elif a.cmd == "poisson":
            pts, nrm = read_cloud(a.cloud)
            v, f, out = poisson(pts, nrm, a.depth, a.scale, a.linear_fit, a.trim, a.threads)
            write_mesh(a.output, v, f)
        elif a.cmd == "offset":
            v, f = read_mesh(a.mesh)
            v, f, out = vdb_offset(v, f, a.delta, a.voxel or None, a.margin, a.adaptivity)
            write_mesh(a.output, v, f)
        elif a.cmd == "two-step":
            out = two_step(a.cloud, a.delta, a.outdir, a.depth, a.voxel or None, a.margin, a.threads)
        elif a.cmd == "components":
            v, f = read_mesh(a.mesh)
            comps = components(v, f, weld=not a.no_weld)
            out = component_summary(comps)
            out["list"] = comps[:50]
        else:
            if a.shape == "sphere":
                v, f = sphere_mesh(a.radius, tol=a.tol)
            else:
                v, f = torus_mesh(a.R, a.r, tol=a.tol)
            write_mesh(a.output, v, f)
            out = {"vertices": len(v), "faces": len(f)}
    except PeerMissing as e:
        print("peer.py: %s" % e, file=sys.stderr)
        return 3
    json.dump(out, sys.stdout)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
