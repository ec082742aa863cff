"""The example scenarios (data): ``mcusim run BOARD --scenario <name>``; see docs/scenarios.md."""
