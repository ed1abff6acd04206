#!/usr/bin/env python3
"""Independent readings of HPGL files and of the Hershey font, for tests/hpgl_oracles.rs.

    hpgl_oracles.py hp2xx FILE [--solid] [OPTION …]
                                  pen-down polylines as GNU hp2xx (Debian package) draws them
                                  (options go to hp2xx, e.g. -W 10000 -H 7200); --solid: every
                                  line type set back to solid first (hp2xx draws the dashes a
                                  plotter would, cncsim the path the tool follows)
    hpgl_oracles.py ezdxf FILE    pen-down polylines and polygon outlines as ezdxf's HP-GL/2
                                  reader (PyPI package ezdxf) draws them
    hpgl_oracles.py hershey       Roman Simplex glyphs as the PyPI package Hershey-Fonts
                                  decodes them (its own copy of the font data)

Output, one item a line: `pen x,y x,y ...` (plotter units) for polylines, and
`char left right | x,y x,y ; x,y ...` (Hershey units, y down) for glyphs.
hp2xx shifts its output so that the drawing's lower-left corner is at 0,0.
"""

import re
import subprocess
import sys
import tempfile

# `LT` with its parameters, where a command starts (after a terminator, a separator or the
# previous command's last number).
LINE_TYPE = re.compile(rb"(?:(?<=^)|(?<=[;\s0-9.]))LT[-+0-9., ]*")


def hp2xx(path, options=()):
    options = list(options)
    if "--solid" in options:
        options.remove("--solid")
        with open(path, "rb") as f:
            text = LINE_TYPE.sub(b"LT", f.read())
        with tempfile.NamedTemporaryFile(suffix=".hp") as solid:
            solid.write(text)
            solid.flush()
            return hp2xx(solid.name, options)
    # -m hpgl writes the drawing back as plain PU/PD vectors in plotter units (-t: true
    # size); labels, circles and arcs come out as the vectors hp2xx draws them with.
    output = subprocess.run(
        ["hp2xx", "-q", "-m", "hpgl", "-t", *options, "-f", "-", path],
        check=True,
        capture_output=True,
    ).stdout.decode("ascii", "replace")
    pen = 1
    current = None
    lines = []
    for command in output.replace("\n", "").split(";"):
        name, arguments = command[:2], command[2:]
        if name == "SP":
            pen = int(float(arguments)) if arguments else 0
            # hp2xx writes `SPn;PDx,y` with the pen still down: the next stroke goes on from
            # the last point, in the new pen.
            current = [pen, [current[1][-1]]] if current else None
        elif name == "PU":
            current = None
            if arguments:
                current = [pen, [tuple(map(float, arguments.split(",")))]]
        elif name == "PD" and arguments:
            point = tuple(map(float, arguments.split(",")))
            if current is None:
                continue
            if len(current[1]) == 1:
                lines.append(current)
            current[1].append(point)
    for pen, points in lines:
        print(pen, " ".join(f"{x:.4f},{y:.4f}" for x, y in points))


def ezdxf_lines(path):
    from ezdxf.addons.hpgl2 import tokenizer
    from ezdxf.addons.hpgl2.backend import Backend
    from ezdxf.addons.hpgl2.interpreter import Interpreter
    from ezdxf.addons.hpgl2.plotter import Plotter

    class Collect(Backend):
        def __init__(self):
            self.lines = []

        def draw_polyline(self, properties, points):
            if len(points) > 1:
                self.lines.append((properties.pen_index, [(p.x, p.y) for p in points]))

        def draw_paths(self, properties, paths, filled):
            for path in paths:
                points = [(p.x, p.y) for p in path.flattening(0.05)]
                if filled and points and points[0] != points[-1]:
                    points.append(points[0])
                if len(points) > 1:
                    self.lines.append((properties.pen_index, points))

    with open(path, "rb") as file:
        data = file.read()
    # ezdxf reads HP-GL/2 after the escape that enters it (or a known BP/IN start); a bare
    # HP-GL/2 file (KiCad's `IN;VS40;…`) gets that escape put in front.
    if b"\x1b%" not in data and not tokenizer.has_known_start_sequence(data):
        data = b"\x1b%1B" + data
    collect = Collect()
    Interpreter(Plotter(collect)).run(tokenizer.hpgl2_commands(data))
    for pen, points in collect.lines:
        print(pen, " ".join(f"{x:.4f},{y:.4f}" for x, y in points))


def hershey():
    from HersheyFonts import HersheyFonts

    font = HersheyFonts()
    font.load_default_font("rowmans")
    for code in range(33, 127):
        glyph = next(iter(font.glyphs_for_text(chr(code))))
        strokes = " ; ".join(
            " ".join(f"{x},{y}" for x, y in stroke) for stroke in glyph.strokes
        )
        left = glyph.left_offset
        print(code, left, left + glyph.char_width, "|", strokes)


if __name__ == "__main__":
    kind = sys.argv[1]
    if kind == "hp2xx":
        hp2xx(sys.argv[2], sys.argv[3:])
    elif kind == "ezdxf":
        ezdxf_lines(sys.argv[2])
    elif kind == "hershey":
        hershey()
    else:
        sys.exit(f"unknown oracle {kind}")
