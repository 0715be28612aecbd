"""An INTO-CPS external objective script (Python 3): how often the valve opened or closed.

python switches.py RESULTS_FOLDER OBJECTIVE_NAME SCENARIO_FOLDER VALVE_COLUMN
"""

import csv
import json
import os
import sys
from itertools import pairwise

folder, name, _scenario_folder, valve_column = sys.argv[1:5]
with open(os.path.join(folder, "results.csv")) as f:
    valve = [float(row[valve_column]) for row in csv.DictReader(f)]
switches = sum(1 for before, after in pairwise(valve) if before != after)

path = os.path.join(folder, "objectives.json")
with open(path) as f:
    objectives = json.load(f)
objectives[name] = switches
with open(path, "w") as f:
    json.dump(objectives, f, sort_keys=True, indent=4, separators=(",", ": "))
