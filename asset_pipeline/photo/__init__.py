"""The photo's view of an asset (docs/fidelity.md): the camera fitted to the photo
(:mod:`.camera`), the photo baked into the part textures (:mod:`.texture`) and the
fidelity score of the built asset against the photo (:mod:`.fidelity`)."""
