"""Many assets: the catalog beside them (:mod:`.registry`, ``OUT/registry.sqlite``), batch
conversion of an image folder (:mod:`.batch`, ``pact convert``) and the worker processes
it runs items in (:mod:`.workers`)."""
