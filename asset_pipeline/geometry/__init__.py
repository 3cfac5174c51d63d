"""Geometry for simulation (docs/architecture.md, "Collision geometry"): part meshes at
metric scale (:mod:`.metric`), convex collision pieces from CoACD (:mod:`.coacd_collision`)
or articulation-aware voxel boxes (:mod:`.voxel_collision`), and the volumes parts sweep
while they move (:mod:`.sweeps`). Closing, cleaning and decimating meshes is the one
toolkit of :mod:`generator.mesh_repair`."""
