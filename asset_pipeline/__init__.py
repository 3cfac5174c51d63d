"""From an articulated object to a validated, catalogued simulation asset, one stage a folder.

``inputs/``      an image folder's photos, part masks and hints (docs/input-format.md)
``photo/``       the photo's camera, the photo baked into textures, the fidelity score
``geometry/``    metric part meshes, light visuals, convex collision pieces, swept volumes
``assets/``      the built-asset model, the rig, the build, and URDF / MJCF / asset.json
``simulation/``  a built asset in SAPIEN: scenes and the one loader
``validate/``    SAPIEN checks, repairs, report.json and previews (docs/validation.md)
``importers/``   PartNet-Mobility folders and CAGE / SINGAPO / PAct outputs as bundles
``catalog/``     the catalog (registry.sqlite), batch conversion and its worker processes
``gallery/``     the HTML gallery of an output folder

The documented Python entry points: ``asset_pipeline.assets.build.build_asset``,
``asset_pipeline.validate.validate_asset``, ``asset_pipeline.assets.folder.load_asset``,
``asset_pipeline.catalog.batch.run_convert``, ``asset_pipeline.importers.import_path`` and
``asset_pipeline.gallery.page.write_gallery``; the ``pact`` command (``pact_cli``) calls them.
"""
