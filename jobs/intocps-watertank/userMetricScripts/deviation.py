"""An INTO-CPS external objective script (Python 3): the rms deviation of the tank level from the
scenario's target level, over the samples of results.csv.

INTO-CPS's calling convention: python deviation.py RESULTS_FOLDER OBJECTIVE_NAME SCENARIO_FOLDER
TIME_COLUMN LEVEL_COLUMN TARGET_FILE. The value goes into RESULTS_FOLDER/objectives.json under
OBJECTIVE_NAME.
"""

import csv
import json
import math
import os
import sys

folder, name, scenario_folder, time_column, level_column, target_file = sys.argv[1:7]
with open(os.path.join(folder, "results.csv")) as f:
    rows = [{key.strip(): float(value) for key, value in row.items()} for row in csv.DictReader(f)]
with open(os.path.join(scenario_folder, target_file)) as f:
    target = json.load(f)["level"]
deviation = math.sqrt(sum((row[level_column] - target) ** 2 for row in rows) / len(rows))

path = os.path.join(folder, "objectives.json")
with open(path) as f:
    objectives = json.load(f)
objectives[name] = deviation
with open(path, "w") as f:
    json.dump(objectives, f, sort_keys=True, indent=4, separators=(",", ": "))
