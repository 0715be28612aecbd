"""dse-runner's one simulation: FMUs, the master, experiments, scenarios and objectives."""
