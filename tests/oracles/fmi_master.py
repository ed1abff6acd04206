"""An independent co-simulation master (FMPy's FMI 3.0 API): validates cncsim's exported plant
FMU with FMPy's validate_fmu, connects it to a controller FMU by variable name (every
controller input from the plant output of the same name, every controller output to the plant
input of the same name), and steps both at the plant's step size from its DefaultExperiment:
at each communication point the controller reads the plant's outputs, steps, and its commands
are held by the plant over the next step.

Writes one row per step: the plant's program_time, then per controller output its value, then
every plant output (full float precision).

usage: fmi_master.py PLANT.fmu CONTROLLER.fmu OUT.csv [NAME=VALUE ...] (controller parameters)
"""

import sys

from fmpy import extract, read_model_description
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu


def instantiate(path, name):
    md = read_model_description(path)
    fmu = FMU3Slave(
        guid=md.guid,
        unzipDirectory=extract(path),
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName=name,
    )
    fmu.instantiate()
    return md, fmu


def main():
    plant_path, controller_path, out_path = sys.argv[1:4]
    parameters = dict(arg.split("=", 1) for arg in sys.argv[4:])

    problems = validate_fmu(plant_path)
    if problems:
        print("validate_fmu:", *problems, sep="\n  ", file=sys.stderr)
        return 1

    plant_md, plant = instantiate(plant_path, "plant")
    ctrl_md, ctrl = instantiate(controller_path, "controller")
    plant_vars = {v.name: v for v in plant_md.modelVariables}
    ctrl_vars = {v.name: v for v in ctrl_md.modelVariables}

    ex = plant_md.defaultExperiment
    start, stop, step = float(ex.startTime), float(ex.stopTime), float(ex.stepSize)
    steps = round((stop - start) / step)

    ctrl_inputs = [v for v in ctrl_md.modelVariables if v.causality == "input"]
    ctrl_outputs = [v for v in ctrl_md.modelVariables if v.causality == "output"]
    missing = [v.name for v in ctrl_inputs if plant_vars.get(v.name, None) is None
               or plant_vars[v.name].causality != "output"]
    missing += [v.name for v in ctrl_outputs if plant_vars.get(v.name, None) is None
                or plant_vars[v.name].causality != "input"]
    if missing:
        print("not connected by name:", ", ".join(missing), file=sys.stderr)
        return 1
    plant_outputs = [v for v in plant_md.modelVariables if v.causality == "output"]
    from_plant = [plant_vars[v.name].valueReference for v in ctrl_inputs]
    to_ctrl = [v.valueReference for v in ctrl_inputs]
    from_ctrl = [v.valueReference for v in ctrl_outputs]
    to_plant = [plant_vars[v.name].valueReference for v in ctrl_outputs]
    recorded = [v.valueReference for v in plant_outputs]
    program_time = plant_vars["program_time"].valueReference

    for name, value in parameters.items():
        ctrl.setFloat64([ctrl_vars[name].valueReference], [float(value)])
    for fmu in (plant, ctrl):
        fmu.enterInitializationMode(startTime=start)
        fmu.exitInitializationMode()

    rows = []
    t = start
    for k in range(steps):
        ctrl.setFloat64(to_ctrl, plant.getFloat64(from_plant))
        ctrl.doStep(currentCommunicationPoint=t, communicationStepSize=step)
        u = ctrl.getFloat64(from_ctrl)
        rows.append(plant.getFloat64([program_time]) + u + plant.getFloat64(recorded))
        plant.setFloat64(to_plant, u)
        plant.doStep(currentCommunicationPoint=t, communicationStepSize=step)
        t = start + (k + 1) * step

    for fmu in (plant, ctrl):
        fmu.terminate()
        fmu.freeInstance()

    with open(out_path, "w") as f:
        header = ["program_time"] + [v.name for v in ctrl_outputs] + [v.name for v in plant_outputs]
        f.write(",".join(header) + "\n")
        for row in rows:
            f.write(",".join(repr(float(x)) for x in row) + "\n")
    print(f"{steps} steps of {step} s from t = {start} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
