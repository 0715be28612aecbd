"""dse-runner's sweeps and search: specs, tasks, Dask, the store, fits."""
