"""The linear plane-strain FEM of the finger shared by L1 and L2 (scikit-fem, P1).

Everything is assembled once per (material, geometry, mesh): the instantaneous
stiffness K0 (scikit-fem form), the element strain operator B, the factorisation of
K0 with the flat face clamped, the contact compliance C0 = (K0⁻¹)_cc condensed exactly
onto the y-DOFs of the surface nodes of the contact strip, and the corpuscle functional
w with ε̄_y = w·u (exact average of the P1 strain over the meshed element).
Forces are per mm of finger length (N/mm), displacements mm, moduli MPa.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from feeler.models.skin.mesh import FingerMesh, MeshSpec, finger_mesh
from feeler.models.skin.params import SkinParams

__all__ = ["FingerFEM", "finger_fem", "elastic_matrices", "strain_operator"]


@dataclass(frozen=True, eq=False)
class FingerFEM:
    """Assembled finger model.

    Attributes:
        mesh: the triangle mesh.
        stiffness (sparse[n_dof, n_dof]): K0 with instantaneous moduli, DOFs (2i, 2i+1).
        strain (sparse[3 n_tri, n_dof]): B, rows (ε_xx, ε_yy, γ_xy) per triangle.
        area_mm2 (ndarray[n_tri]): triangle areas.
        elastic (ndarray[n_tri, 3, 3]): instantaneous plane-strain D per triangle, MPa.
        free (ndarray[n_free]): unclamped DOFs; ``lu`` factorises K0[free, free].
        contact_dof (ndarray[n_c]): y-DOFs of the contact-strip surface nodes (sorted by X).
        contact_pos (ndarray[n_c]): position of those DOFs within ``free``.
        compliance (ndarray[n_c, n_c]): C0 = (K0⁻¹)_cc, mm per N/mm.
        corpuscle (ndarray[n_dof]): w, with ε̄_y = w·u.
        adjoint (ndarray[n_c]): (K0⁻¹ w) at the contact DOFs — the corpuscle strain per
            unit contact force (one adjoint solve; K0 symmetric).
    """

    mesh: FingerMesh
    stiffness: sp.csr_matrix
    strain: sp.csr_matrix
    area_mm2: np.ndarray
    elastic: np.ndarray
    free: np.ndarray
    lu: object
    contact_dof: np.ndarray
    contact_pos: np.ndarray
    compliance: np.ndarray
    corpuscle: np.ndarray
    adjoint: np.ndarray

    @property
    def surface_x_mm(self) -> np.ndarray:
        return self.mesh.points[0, self.mesh.surface]

    @property
    def surface_y_mm(self) -> np.ndarray:
        """Height of the undeformed surface nodes above the plate's initial level."""
        return self.mesh.points[1, self.mesh.surface]

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """u with K0 u = rhs on the free DOFs and u = 0 on the clamped face.

        rhs (ndarray[n_dof] or [n_dof, k]) → ndarray of the same shape.
        """
        u = np.zeros_like(rhs, dtype=float)
        u[self.free] = self.lu.solve(np.ascontiguousarray(rhs[self.free]))
        return u


def elastic_matrices(e_mpa: np.ndarray, nu: float) -> np.ndarray:
    """Plane-strain D (ndarray[n, 3, 3], Voigt with engineering shear) for moduli e_mpa[n]."""
    lam = e_mpa * nu / ((1 + nu) * (1 - 2 * nu))
    mu = e_mpa / (2 * (1 + nu))
    d = np.zeros((len(e_mpa), 3, 3))
    d[:, 0, 0] = d[:, 1, 1] = lam + 2 * mu
    d[:, 0, 1] = d[:, 1, 0] = lam
    d[:, 2, 2] = mu
    return d


def strain_operator(points: np.ndarray, tri: np.ndarray):
    """P1 strain operator B (sparse[3 n_tri, 2 n_nodes]) and triangle areas (mm²)."""
    x, y = points[:, tri]
    area2 = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0])
    dndx = np.stack([y[1] - y[2], y[2] - y[0], y[0] - y[1]]) / area2
    dndy = np.stack([x[2] - x[1], x[0] - x[2], x[1] - x[0]]) / area2
    n_tri = tri.shape[1]
    rows, cols, vals = [], [], []
    e = np.arange(n_tri)
    for k in range(3):
        ux, uy = 2 * tri[k], 2 * tri[k] + 1
        for r, c, v in ((3 * e, ux, dndx[k]), (3 * e + 1, uy, dndy[k]),
                        (3 * e + 2, ux, dndy[k]), (3 * e + 2, uy, dndx[k])):
            rows.append(r), cols.append(c), vals.append(v)
    b = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(3 * n_tri, 2 * points.shape[1]))
    return b, area2 / 2


def finger_fem(params: SkinParams, spec: MeshSpec) -> FingerFEM:
    """Assemble (and cache) the finger FEM for the material/geometry of ``params``."""
    return _fem_cached(params.e_mpa, params.nu, finger_mesh(params, spec))


@functools.lru_cache(maxsize=4)
def _fem_cached(e_layers: tuple, nu: float, mesh: FingerMesh) -> FingerFEM:
    import skfem
    from skfem.helpers import ddot, sym_grad, trace

    e_tri = np.asarray(e_layers)[mesh.layer]
    skmesh = skfem.MeshTri(np.ascontiguousarray(mesh.points), np.ascontiguousarray(mesh.triangles, dtype=np.int32))
    basis = skfem.Basis(skmesh, skfem.ElementVector(skfem.ElementTriP1()), intorder=1)

    @skfem.BilinearForm
    def elasticity(u, v, w):
        eu = sym_grad(u)
        return 2 * w.mu * ddot(eu, sym_grad(v)) + w.lam * trace(eu) * trace(sym_grad(v))

    nqp = basis.X.shape[1]
    lam = (e_tri * nu / ((1 + nu) * (1 - 2 * nu)))[:, None] * np.ones((1, nqp))
    mu = (e_tri / (2 * (1 + nu)))[:, None] * np.ones((1, nqp))
    k0 = elasticity.assemble(basis, lam=lam, mu=mu).tocsr()
    b, area = strain_operator(mesh.points, mesh.triangles)
    clamped = np.concatenate([2 * mesh.clamped, 2 * mesh.clamped + 1])
    free = np.setdiff1d(np.arange(2 * mesh.n_nodes), clamped)
    lu = splu(k0[free][:, free].tocsc(), permc_spec="COLAMD")
    contact_dof = 2 * mesh.surface + 1
    contact_pos = np.searchsorted(free, contact_dof)
    compliance = np.empty((len(contact_dof), len(contact_dof)))
    for start in range(0, len(contact_dof), 64):  # SuperLU is slow on very wide right-hand sides
        cols = np.arange(start, min(start + 64, len(contact_dof)))
        rhs = np.zeros((len(free), len(cols)), order="F")
        rhs[contact_pos[cols], np.arange(len(cols))] = 1.0
        compliance[:, cols] = lu.solve(rhs)[contact_pos]
    compliance = 0.5 * (compliance + compliance.T)
    corp = mesh.corpuscle
    weights = np.zeros(3 * mesh.triangles.shape[1])
    weights[3 * np.flatnonzero(corp) + 1] = area[corp] / area[corp].sum()
    corpuscle = b.T @ weights
    adjoint = lu.solve(corpuscle[free])[contact_pos]
    return FingerFEM(mesh=mesh, stiffness=k0, strain=b, area_mm2=area,
                     elastic=elastic_matrices(e_tri, nu), free=free, lu=lu,
                     contact_dof=contact_dof, contact_pos=contact_pos, compliance=compliance,
                     corpuscle=corpuscle, adjoint=adjoint)
