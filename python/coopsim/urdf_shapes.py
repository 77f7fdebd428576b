"""The collision shapes of a URDF link (coopsim.urdf's reading of <collision>): boxes, spheres and
cylinders as coopsim's LinkBox shapes (Bullet's own in the world), meshes read with trimesh as the convex
hull of a bounded number of their hull's vertices (farthest-point sampling)."""
from __future__ import annotations

import warnings

import numpy as np

from ._core import LinkBox


def _hull_vertices(points: np.ndarray, count: int) -> np.ndarray:
    """At most `count` of a convex hull's vertices (k, 3), by farthest-point sampling: first the vertex
    farthest from their centroid, then each time the vertex farthest from those chosen (ties: the first
    in order). Deterministic; the hull of the points kept lies inside the full one and keeps its extremes."""
    if len(points) <= count:
        return points
    d = np.linalg.norm(points - points.mean(axis=0), axis=1)
    chosen = [int(np.argmax(d))]
    dist = np.linalg.norm(points - points[chosen[0]], axis=1)
    for _ in range(count - 1):
        k = int(np.argmax(dist))
        chosen.append(k)
        dist = np.minimum(dist, np.linalg.norm(points - points[k], axis=1))
    return points[np.sort(chosen)]


def _mesh_hull(path: str, scale, count: int) -> np.ndarray:
    """The convex hull's vertices (k, 3) m of the mesh file at `path` scaled by `scale` (3,), at most
    `count` of them (_hull_vertices); read with trimesh. Raises on a file trimesh cannot read or a mesh
    without volume."""
    import trimesh

    mesh = trimesh.load(path, force="mesh")
    v = np.asarray(mesh.vertices, dtype=float) * np.asarray(scale, dtype=float)
    if len(v) < 4:
        raise ValueError("fewer than 4 vertices")
    hull = trimesh.convex.convex_hull(v)
    return _hull_vertices(np.asarray(hull.vertices, dtype=float), count)


def _collision_shapes(link, ln, body, X, base_dir, snap, hull_points, read):
    """The LinkBoxes of URDF link `link` (name ln) on robot link `body`, X (4, 4) its frame in the body's DH
    frame: its <collision> shapes (or its <visual> ones when it has no collision): boxes, spheres and
    cylinders as such, meshes as the convex hull of their (scaled) vertices, at most `hull_points` of them
    (farthest-point sampling of the hull's vertices, _hull_vertices). A mesh file not found or that trimesh
    cannot read: a RuntimeWarning naming it, and the link keeps its other shapes (a robot left without any
    gets the default boxes); hull_points = 0: meshes left out, silently. read: coopsim.urdf's readers
    (_attr, _floats, _mesh_path, _pose), whose checks and messages the shapes share."""
    _attr, _floats, _mesh_path, _pose = read

    out = []
    shapes = link.findall("collision") or link.findall("visual")
    for k, sh in enumerate(shapes):
        what = f"link {ln!r} {sh.tag}"
        label = sh.get("name") or f"{ln}_{k}"
        g = sh.find("geometry")
        if g is None:
            continue
        T = X @ _pose(sh, what, snap)
        box, sphere, cyl, mesh = g.find("box"), g.find("sphere"), g.find("cylinder"), g.find("mesh")
        if box is not None:
            size = _floats(box.get("size"), 3, f"link {ln!r} box size")
            if min(size) <= 0:
                raise ValueError(f"link {ln!r}: box sizes must be > 0, got {size}")
            out.append(LinkBox(body, 0.5 * np.array(size), T, label))
        elif sphere is not None:
            out.append(LinkBox.sphere(body, _attr(sphere, "radius", f"{what} sphere"), T, label))
        elif cyl is not None:
            out.append(LinkBox.cylinder(body, _attr(cyl, "radius", f"{what} cylinder"),
                                        _attr(cyl, "length", f"{what} cylinder"), T, label))
        elif mesh is not None and sh.tag == "collision" and hull_points > 0:
            fn = mesh.get("filename") or ""
            scale = _floats(mesh.get("scale", "1 1 1"), 3, f"{what} mesh scale")
            path = _mesh_path(fn, base_dir) if fn else None
            try:
                if path is None:
                    raise FileNotFoundError("file not found")
                points = _mesh_hull(path, scale, hull_points)
                out.append(LinkBox.hull(body, points, T, label))
            except Exception as e:  # noqa: BLE001 - any reader's failure: the shape is left out, said so
                warnings.warn(f"{what}: collision mesh {fn!r} could not be read ({type(e).__name__}: {e}); "
                              "left out: the link keeps its other shapes (a robot without any gets the default "
                              "boxes)", RuntimeWarning, stacklevel=4)
    return out
