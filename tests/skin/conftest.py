"""Shared small meshes for the skin tests (kept coarse: the whole suite has ~90 s)."""
from feeler.models.skin.mesh import MeshSpec

# coarse but valid: ~2k nodes, ~0.05 s per L2 time step on a loaded 2-core machine
SMALL = MeshSpec(h_contact_mm=0.05, h_corpuscle_mm=0.02, h_far_mm=1.5, grade=0.4)
# for the Hertz check: homogeneous finger, small press, fine surface
HERTZ = MeshSpec(h_contact_mm=0.02, h_corpuscle_mm=0.02, h_far_mm=1.5, grade=0.3,
                 contact_half_width_mm=2.5, band_half_width_mm=1.0, band_depth_mm=0.3)
COARSE_DT = 0.05  # mm of travel per slide step in the tests
