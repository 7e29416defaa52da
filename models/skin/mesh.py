"""gmsh mesh of the three-layer half-cylinder finger, refined at the contact strip and
around the corpuscle element (which is meshed exactly as its own region).

FEM coordinates (mm): X along the scan, Y upwards; the finger is the lower half of the
disk of radius R centred at (0, R), so its lowest point touches the plate at (0, 0) and
its flat face Y = R is clamped to the (rigid) bone/nail. Depth below the skin at X = 0
is Y. gmsh runs in-process without a GUI and without signal handlers (safe off the main
thread); calls are serialised by a lock because gmsh keeps global state.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import threading
from dataclasses import dataclass

import numpy as np

from feeler.errors import ArgumentError
from feeler.models.skin.params import SkinParams

__all__ = ["MeshSpec", "FingerMesh", "finger_mesh", "MIN_CORPUSCLE_TRIANGLES"]

MIN_CORPUSCLE_TRIANGLES = 8
_LOCK = threading.Lock()


@dataclass(frozen=True)
class MeshSpec:
    """Target element sizes (mm) of the finger mesh.

    Attributes:
        h_contact_mm (float): size at the skin surface along the contact strip.
        h_corpuscle_mm (float): size inside and around the corpuscle element; at most
            half the element's smaller side, else the average is not resolved.
        h_far_mm (float): largest size, far from the contact.
        grade (float): growth of the size per mm of distance from the refined zones.
        contact_half_width_mm (float): |X| of the strip whose surface nodes may touch.
        band_half_width_mm, band_depth_mm (float): the block of skin above and around the
            corpuscle kept at ``h_contact_mm`` throughout (graded meshes there alias the
            surface field and make the strain rate noisy: measured).
    """

    h_contact_mm: float = 0.025
    h_corpuscle_mm: float = 0.01
    h_far_mm: float = 0.8
    grade: float = 0.25
    contact_half_width_mm: float = 4.5
    band_half_width_mm: float = 1.5
    band_depth_mm: float = 0.75

    def refined(self, factor: float) -> "MeshSpec":
        """A copy with the contact, corpuscle and far sizes divided by ``factor``."""
        return dataclasses.replace(self, h_contact_mm=self.h_contact_mm / factor,
                                   h_corpuscle_mm=self.h_corpuscle_mm / factor,
                                   h_far_mm=self.h_far_mm / factor)

    def check(self, params: SkinParams) -> None:
        """Raise ArgumentError when a size cannot resolve the corpuscle or the geometry."""
        for name in ("h_contact_mm", "h_corpuscle_mm", "h_far_mm", "grade", "contact_half_width_mm",
                     "band_half_width_mm", "band_depth_mm"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ArgumentError(f"mesh.{name}", v, "must be a finite number > 0")
        limit = 0.5 * min(params.corpuscle_width_mm, params.corpuscle_height_mm)
        if self.h_corpuscle_mm > limit:
            raise ArgumentError("mesh.h_corpuscle_mm", self.h_corpuscle_mm,
                                f"too coarse for the {params.corpuscle_width_mm * 1e3:g} × "
                                f"{params.corpuscle_height_mm * 1e3:g} µm corpuscle element: must be <= {limit:g} mm")
        if self.h_contact_mm > params.corpuscle_depth_mm / 4:
            raise ArgumentError("mesh.h_contact_mm", self.h_contact_mm,
                                f"too coarse to carry the surface field to the corpuscle: must be "
                                f"<= {params.corpuscle_depth_mm / 4:g} mm (a quarter of its depth)")
        if self.contact_half_width_mm >= params.radius_mm:
            raise ArgumentError("mesh.contact_half_width_mm", self.contact_half_width_mm,
                                f"must be < the finger radius {params.radius_mm} mm")


@dataclass(frozen=True, eq=False)
class FingerMesh:
    """A triangle mesh of the finger (P1), as plain arrays.

    Attributes:
        points (ndarray[2, n_nodes]): X, Y in mm.
        triangles (ndarray[3, n_tri]): node indices, counter-clockwise.
        layer (ndarray[n_tri]): 0 epidermis, 1 dermis, 2 hypodermis.
        corpuscle (ndarray[n_tri] bool): triangles of the corpuscle element (dermis).
        clamped (ndarray[k]): nodes on the flat face Y = R.
        surface (ndarray[m]): skin-surface nodes of the contact strip, sorted by X.
    """

    points: np.ndarray
    triangles: np.ndarray
    layer: np.ndarray
    corpuscle: np.ndarray
    clamped: np.ndarray
    surface: np.ndarray

    @property
    def n_nodes(self) -> int:
        return self.points.shape[1]


def finger_mesh(params: SkinParams, spec: MeshSpec) -> FingerMesh:
    """Mesh the finger of ``params`` with the sizes of ``spec`` (cached per pair)."""
    spec.check(params)
    return _mesh_cached(_geometry_key(params), spec)


def _geometry_key(p: SkinParams) -> tuple:
    return (p.radius_mm, p.thickness_mm, p.corpuscle_width_mm, p.corpuscle_height_mm,
            p.corpuscle_depth_mm)


@functools.lru_cache(maxsize=8)
def _mesh_cached(key: tuple, spec: MeshSpec) -> FingerMesh:
    with _LOCK:
        import gmsh
        gmsh.initialize(interruptible=False)
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.model.add("finger")
            tags = _build_geometry(gmsh, key)
            _size_field(gmsh, key, spec)
            gmsh.model.mesh.generate(2)
            mesh = _extract(gmsh, key, spec, tags)
        finally:
            gmsh.finalize()
    n_corp = int(mesh.corpuscle.sum())
    if n_corp < MIN_CORPUSCLE_TRIANGLES:
        raise ArgumentError("mesh.h_corpuscle_mm", spec.h_corpuscle_mm,
                            f"gives {n_corp} triangles in the corpuscle element; need >= "
                            f"{MIN_CORPUSCLE_TRIANGLES}: refine the mesh")
    return mesh


def _build_geometry(gmsh, key):
    radius, (t_epi, t_derm), w, h, depth = key
    occ = gmsh.model.occ
    big = 4 * radius

    def half_disk(r):
        disk = occ.addDisk(0.0, radius, 0.0, r, r)
        upper = occ.addRectangle(-big, radius, 0.0, 2 * big, big)
        out, _ = occ.cut([(2, disk)], [(2, upper)])
        return out[0]

    inputs = [half_disk(radius), half_disk(radius - t_epi), half_disk(radius - t_epi - t_derm),
              (2, occ.addRectangle(-w / 2, depth - h / 2, 0.0, w, h))]
    _, pieces = occ.fragment(inputs, [])
    occ.synchronize()
    owners: dict[int, set[int]] = {}
    for i, group in enumerate(pieces):
        for dim, tag in group:
            owners.setdefault(tag, set()).add(i)
    # a piece belongs to the innermost input containing it
    return {tag: (3 if 3 in s else max(s) if max(s) < 3 else 1) for tag, s in owners.items()}


def _size_field(gmsh, key, spec: MeshSpec):
    radius, _, w, h, depth = key
    f = gmsh.model.mesh.field
    contact = f.add("MathEval")
    dist_surface = f"max({radius} - sqrt(x*x + (y - {radius})*(y - {radius})), 0)"
    dist_strip = f"max(abs(x) - {spec.contact_half_width_mm}, 0)"
    f.setString(contact, "F", f"{spec.h_contact_mm} + {spec.grade}*({dist_surface} + {dist_strip})")
    corp = f.add("MathEval")
    dist_corp = f"max(max(abs(x) - {w / 2}, abs(y - {depth}) - {h / 2}), 0)"
    f.setString(corp, "F", f"{spec.h_corpuscle_mm} + {spec.grade}*{dist_corp}")
    band = f.add("MathEval")
    dist_band = (f"max(abs(x) - {spec.band_half_width_mm}, 0) + "
                 f"max({radius} - sqrt(x*x + (y - {radius})*(y - {radius})) - {spec.band_depth_mm}, 0)")
    f.setString(band, "F", f"{spec.h_contact_mm} + {spec.grade}*({dist_band})")
    both = f.add("Min")
    f.setNumbers(both, "FieldsList", [contact, corp, band])
    f.setAsBackgroundMesh(both)
    for name, value in (("Mesh.MeshSizeExtendFromBoundary", 0), ("Mesh.MeshSizeFromPoints", 0),
                        ("Mesh.MeshSizeFromCurvature", 0), ("Mesh.MeshSizeMax", spec.h_far_mm),
                        ("Mesh.Algorithm", 6)):
        gmsh.option.setNumber(name, value)


def _extract(gmsh, key, spec: MeshSpec, owner: dict[int, int]) -> FingerMesh:
    radius = key[0]
    tags, coords, _ = gmsh.model.mesh.getNodes()
    index = np.full(int(tags.max()) + 1, -1)
    index[tags.astype(int)] = np.arange(len(tags))
    points = coords.reshape(-1, 3)[:, :2].T.copy()
    tris, region = [], []
    for dim, tag in gmsh.model.getEntities(2):
        etypes, _, enodes = gmsh.model.mesh.getElements(dim, tag)
        for et, nodes in zip(etypes, enodes):
            if et != 2:
                continue
            t = index[nodes.astype(int)].reshape(-1, 3)
            tris.append(t)
            region.append(np.full(len(t), owner[tag]))
    tri = np.concatenate(tris).T
    region = np.concatenate(region)
    x, y = points[:, tri]
    area2 = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0])
    tri[[1, 2]] = np.where(area2 < 0, tri[[2, 1]], tri[[1, 2]])
    X, Y = points
    on_arc = np.abs(np.hypot(X, Y - radius) - radius) < 1e-7 * radius
    surface = np.flatnonzero(on_arc & (Y < radius) & (np.abs(X) <= spec.contact_half_width_mm))
    surface = surface[np.argsort(X[surface])]
    clamped = np.flatnonzero(np.abs(Y - radius) < 1e-9 * radius)
    layer = np.where(region == 3, 1, region)
    return FingerMesh(points=points, triangles=tri, layer=layer, corpuscle=region == 3,
                      clamped=clamped, surface=surface)
