"""The built asset: its one model (:mod:`.built_asset`), the rig that makes it from an
object (:mod:`.rig`), the build stage (:mod:`.build`), and its files: the folder layout
(:mod:`.layout`, :mod:`.folder`) with one writer and one reader per format
(:mod:`.urdf`, :mod:`.mjcf`, :mod:`.asset_json`, :mod:`.mesh_files`)."""
