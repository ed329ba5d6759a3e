"""Charts -> packed UV atlas, textures, OBJ/GLB export, xatlas, and one UV-metrics harness.

Torch-free (plain meshes with UVs). Entry points: ``texture.pipeline.export_run``,
``texture.pipeline.uv_mesh_file``, ``texture.compare.compare_run``,
``texture.harness.measure`` / ``per_face_distortions`` / ``uv_islands``. See docs/texture.md.
"""
