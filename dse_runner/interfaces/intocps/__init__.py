"""INTO-CPS projects run unchanged (docs/intocps.md).

* formats.py: the dse.json and coe.json as pydantic models (the mm.json is
  read by simulation/multimodel.py);
* project.py: where a DSE's multi-model and co-simulation config are, found
  the way the INTO-CPS application associates them;
* convert.py: a DSE config, its mm.json and coe.json made one of our
  space specs, which the rest of the tool runs like any space.yaml;
* results.py: INTO-CPS's result files (dseResults.csv, results.html,
  ranking.json, graphs/pareto.png) written from our ranking.
"""
