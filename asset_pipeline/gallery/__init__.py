"""The gallery of an output folder (``pact gallery``): the page (:mod:`.page`) and its
browser-side viewer (``web/``)."""
