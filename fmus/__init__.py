"""Our FMUs' C sources: the Robotti vehicle and its effects variant, the replay and path controllers, and
the shared FMI layer they build on (common/). A folder of the checkout's top level, shipped inside the
wheel as ``dse_runner.bundled.fmus`` (pyproject.toml maps it there) and named ``bundled:fmus/...`` in
files; simulation/build.py compiles a folder on first use."""
