"""Builds a controller FMU with a tool other than cncsim: FMPy's FMI 3.0 source template
(fmpy.template: modelDescription.xml and model.c rendered from FMPy's Jinja templates) with a
positional PID with feed-forward filled into its fmi3DoStep, compiled by the system C compiler
against FMPy's FMI 3.0 headers into binaries/x86_64-linux/<id>.so.

The law is LinuxCNC's positional PID as cncsim's built-in `type = "pid"` computes it (the
same operations in the same order, so the two agree to the last bit):

    e = setpoint_position - measured_position
    I' = I + T e
    u* = kp e + ki I' + kd (e - e_prev) / T + (bias + ff0 x + ff1 v + ff2 a)
    u = clamp(u*, -output_limit, output_limit); I = I' unless winding up; e_prev = e

Parameters per axis <a>: kp_<a>, ki_<a>, kd_<a>, ff1_<a>, ff2_<a>, output_limit_<a>;
`fail_at_step` (0: never) makes fmi3DoStep return fmi3Error at that step (tests of a
controller that fails midway).

usage: fmi_controller.py OUT.fmu AXES (e.g. xyz) [--cc gcc]
"""

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile

import fmpy
from fmpy.model_description import (
    CoSimulation,
    DefaultExperiment,
    ModelDescription,
    ModelVariable,
    ScalarVariable,
    Unknown,
)
import jinja2

MODEL_IDENTIFIER = "pid_controller"
PARAMETERS = [
    ("kp", "0"),
    ("ki", "0"),
    ("kd", "0"),
    ("bias", "0"),
    ("ff0", "0"),
    ("ff1", "0"),
    ("ff2", "0"),
    ("output_limit", "1e300"),
]
INPUTS = [
    "setpoint_position",
    "setpoint_velocity",
    "setpoint_acceleration",
    "measured_position",
]
STATES = ["integral", "previous_error"]


def description(axes, period):
    md = ModelDescription()
    md.fmiVersion = "3.0"
    md.modelName = MODEL_IDENTIFIER
    md.description = "positional PID with feed-forward, per axis (FMPy template)"
    md.generationTool = f"FMPy {fmpy.__version__} template"
    md.generationDateAndTime = "2026-01-01T00:00:00Z"
    # Deterministic: the same source gives the same FMU.
    md.instantiationToken = "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, "cncsim/pid_controller/" + axes)) + "}"
    md.coSimulation = CoSimulation(modelIdentifier=MODEL_IDENTIFIER)
    md.defaultExperiment = DefaultExperiment(startTime="0.0", stopTime="1.0", stepSize=repr(period))
    vr = 0

    def add(variable):
        nonlocal vr
        md.modelVariables.append(variable)
        vr += 1

    add(ScalarVariable(name="time", valueReference=vr, type="Float64", causality="independent",
                       variability="continuous", description="time"))
    add(ScalarVariable(name="period", valueReference=vr, type="Float64", start=repr(period),
                       causality="parameter", variability="fixed", description="servo period (s)"))
    add(ScalarVariable(name="fail_at_step", valueReference=vr, type="Float64", start="0",
                       causality="parameter", variability="fixed",
                       description="return fmi3Error at this step (0: never)"))
    add(ScalarVariable(name="steps", valueReference=vr, type="Float64",
                       causality="local", variability="discrete", description="steps done"))
    for a in axes:
        for name, start in PARAMETERS:
            add(ScalarVariable(name=f"{name}_{a}", valueReference=vr, type="Float64", start=start,
                               causality="parameter", variability="fixed", description=name))
        for name in INPUTS:
            add(ModelVariable(name=f"{name}_{a}", valueReference=vr, type="Float64", start="0",
                              causality="input", variability="discrete", description=name))
        command = ModelVariable(name=f"command_{a}", valueReference=vr, type="Float64",
                                causality="output", variability="discrete",
                                description="amplifier input")
        add(command)
        md.outputs.append(Unknown(variable=command))
        md.initialUnknowns.append(Unknown(variable=command))
        for name in STATES:
            add(ScalarVariable(name=f"{name}_{a}", valueReference=vr, type="Float64",
                               causality="local", variability="discrete", description=name))
    return md


def law(axes):
    """The body of fmi3DoStep: the PID of every axis, in cncsim's operation order."""
    lines = [
        "    Model* model = (Model*)instance;",
        "    (void)currentCommunicationPoint; (void)communicationStepSize;",
        "    (void)noSetFMUStatePriorToCurrentPoint;",
        "    *eventHandlingNeeded = fmi3False; *terminateSimulation = fmi3False;",
        "    *earlyReturn = fmi3False;",
        "    *lastSuccessfulTime = currentCommunicationPoint + communicationStepSize;",
        "    model->steps += 1;",
        "    if (model->fail_at_step > 0 && model->steps >= model->fail_at_step) {",
        '        model->logMessage(model->instanceEnvironment, fmi3Error, "logStatusError", "fail_at_step reached");',
        "        return fmi3Error;",
        "    }",
        "    const double T = model->period;",
    ]
    for a in axes:
        m = lambda n: f"model->{n}_{a}"
        lines += [
            "    {",
            f"        const double e = {m('setpoint_position')} - {m('measured_position')};",
            f"        const double integral = {m('integral')} + T * e;",
            f"        const double d_term = {m('kd')} * (e - {m('previous_error')}) / T;",
            f"        const double feed_forward = {m('bias')} + {m('ff0')} * {m('setpoint_position')}"
            f" + {m('ff1')} * {m('setpoint_velocity')} + {m('ff2')} * {m('setpoint_acceleration')};",
            f"        const double unclamped = {m('kp')} * e + {m('ki')} * integral + d_term + feed_forward;",
            f"        const double limit = {m('output_limit')};",
            "        const double u = unclamped < -limit ? -limit : (unclamped > limit ? limit : unclamped);",
            "        const int winding_up = u != unclamped && copysign(1.0, e) == copysign(1.0, unclamped);",
            f"        if (!winding_up) {{ {m('integral')} = integral; }}",
            f"        {m('command')} = u;",
            f"        {m('previous_error')} = e;",
            "    }",
        ]
    lines.append("    return fmi3OK;")
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("out")
    parser.add_argument("axes")
    parser.add_argument("--period", type=float, default=1e-3)
    parser.add_argument("--cc", default=os.environ.get("CC", "gcc"))
    args = parser.parse_args()

    md = description(args.axes, args.period)
    templates = os.path.join(os.path.dirname(fmpy.__file__), "templates")
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(templates), trim_blocks=True)
    xml = env.get_template("modelDescription.xml").render(modelDescription=md)
    c = env.get_template("model.c").render(modelDescription=md, fmpyVersion=fmpy.__version__)

    # Fill the law into the template's empty fmi3DoStep.
    head = c.index("fmi3Status fmi3DoStep(")
    body = c.index("{", head) + 1
    end = c.index("return fmi3OK;\n}", body) + len("return fmi3OK;\n")
    c = "#include <math.h>\n#include <stdlib.h>\n" + c[:body] + "\n" + law(args.axes) + c[end:]

    with tempfile.TemporaryDirectory() as tmp:
        os.makedirs(os.path.join(tmp, "sources"))
        os.makedirs(os.path.join(tmp, "binaries", "x86_64-linux"))
        with open(os.path.join(tmp, "modelDescription.xml"), "w") as f:
            f.write(xml)
        source = os.path.join(tmp, "sources", "model.c")
        with open(source, "w") as f:
            f.write(c)
        headers = os.path.join(os.path.dirname(fmpy.__file__), "c-code")
        library = os.path.join(tmp, "binaries", "x86_64-linux", MODEL_IDENTIFIER + ".so")
        # -ffp-contract=off: no fused multiply-add, the operations as written (as Rust does).
        subprocess.check_call([args.cc, "-std=c99", "-O2", "-ffp-contract=off", "-shared", "-fPIC",
                               "-I", headers, "-o", library, source, "-lm"])
        with zipfile.ZipFile(args.out, "w", zipfile.ZIP_DEFLATED) as z:
            for root, _, files in os.walk(tmp):
                for name in sorted(files):
                    path = os.path.join(root, name)
                    z.write(path, os.path.relpath(path, tmp))
    print(args.out)


if __name__ == "__main__":
    sys.exit(main())
