"""The one mesh-repair toolkit of the project: closing meshes (:mod:`.closing`: watertight,
consistently wound, positive volume) and cleaning part geometry (:mod:`.cleaning`: debris
and slivers dropped, one solid piece per part plus its handle). Generators clean their
output with it and the asset build closes its part meshes with it."""
