# SPDX-License-Identifier: BSD-2-Clause
"""Run one SSP in OMSimulator 3's Python package and print the values asked for, as one line
``RESULT {json}`` (a child process of the conformance tests: a crash of OMSimulator ends only it).

Arguments: the package folder, the archive, stop time, step, a temporary folder, and a JSON list of
``[system, [element, ..., variable]]`` names."""

import json
import sys

sys.path.insert(0, sys.argv[1])  # the prebuilt package lives outside any environment

from OMSimulator import SSP, Capi, CRef  # noqa: E402

Capi.setLogFile(f"{sys.argv[5]}/omsimulator.log")
model = SSP(sys.argv[2], temp_dir=sys.argv[5]).instantiate()
model.setResultFile(f"{sys.argv[5]}/result.csv")
model.setStopTime(float(sys.argv[3]))
model.setFixedStepSize(float(sys.argv[4]))
model.initialize()
model.simulate()
values: dict[str, float | str] = {}
for system, path in json.loads(sys.argv[6]):
    try:
        values[".".join(path)] = float(model.getValue(CRef(system, *path)))
    except Exception as exc:  # noqa: BLE001 - the package raises what it likes; the value is the message
        values[".".join(path)] = str(exc)
model.terminate()
model.delete()
print("RESULT " + json.dumps(values))
