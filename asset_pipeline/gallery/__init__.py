"""The gallery of an output folder (``pact gallery``): the page (:mod:`.page`), its local
server (:mod:`.server`), the mask editor's server side (:mod:`.editor`) and the
browser-side viewer and editor (``web/``); docs/gallery.md."""
