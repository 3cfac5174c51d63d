"""The ``pact`` command line (:mod:`pact_cli.main`): a thin layer over every package.

It sits above ``tasks``, ``sim_envs``, ``asset_pipeline`` and ``generator`` so that it can
call all of them while they keep their one-way dependencies.
"""
