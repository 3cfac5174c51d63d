"""Stage 1 of a conversion, the input: an image folder's photos, part masks and hints
(docs/input-format.md): finding the items (:mod:`.folder`), reading and checking the photo
(:mod:`.photo`), its part mask (:mod:`.mask`) and its hints (:mod:`.hints`), and the ids
the assets will take (:mod:`.asset_ids`)."""
