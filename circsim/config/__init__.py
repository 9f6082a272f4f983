"""A scenario: what an experiment is, as validated, frozen values.

* :mod:`.types` — every section's dataclass (world, robots, laser, SLAM, network, outputs); imports
  nothing of ours, so every bench module can read its configuration from here;
* :mod:`.scenario` — the loader: YAML → :class:`~circsim.config.scenario.Scenario`, ``--set`` overrides,
  the bundled scenarios, the merger section; :mod:`.schema` (every other section's keys and their
  checks), :mod:`.validate` (the schema's checkers) and :mod:`.geometry` (the scene must make sense);
* :mod:`.reference_doc` — docs/scenario-reference.md, generated from the schema.
"""
