"""A built asset in SAPIEN: scenes that work on CPU machines and the one loader of built
assets (:mod:`.sapien_scenes`), and the loader settings validation and the tasks share
(:mod:`.sim_options`)."""
