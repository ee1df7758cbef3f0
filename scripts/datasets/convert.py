#!/usr/bin/env python3
"""Convert the open laser-tracker datasets into robocal's measurement format.

Reads the source files as published (a copy lies in ../shared/data of the development machines)
and writes, for each arm, `robot.toml` (the maker's published nominal table as modified DH), one
measurement CSV per source file, and `targets.csv` (the test poses' targets for `robocal
compensate`); the README and licence notice of each folder are written by hand.

  python3 scripts/datasets/convert.py SOURCE_DIR [--out datasets]

SOURCE_DIR holds `serial_robots_datasets/` (UR5 and WAM, P. Jacobi, MIT licence).

UR5 and WAM rows: the source gives the target position (`x_t, y_t, z_t`, mm, robot base frame),
the difference to the position reached (`x_dif, y_dif, z_dif`, mm) and the commanded joint
angles (deg). The measured point is written as target + dif (the source does not state the
sign; see each folder's README), the targets kept beside it (`x_t, y_t, z_t`) for the test that
checks the nominal table against them, the source's `step_order` as `seq`. Every row has load 0
(the source names no payload).

Standard DH (Craig's distal form, `RotZ(θ) TransZ(d) TransX(a) RotX(α)` per joint) becomes modified
DH (`RotX(α) TransX(a) RotZ(θ) TransZ(d)`) by moving each joint's `a` and `α` onto the next one:
MDH row i takes `α_{i-1}, a_{i-1}` and `d_i, θ_i`. The last joint's `a` and `α` are zero for both
arms, so the tool point stays in the same flange frame.
"""

import argparse
import csv
import math
import sys
from pathlib import Path

# Standard DH as published by the makers: d (mm), a (mm), alpha (deg) per joint, base to tip.
UR5_DH = {
    "d": [89.159, 0.0, 0.0, 109.15, 94.65, 82.3],
    "a": [0.0, -425.0, -392.25, 0.0, 0.0, 0.0],
    "alpha": [90.0, 0.0, 0.0, 90.0, -90.0, 0.0],
}
WAM_DH = {
    "d": [0.0, 0.0, 550.0, 0.0, 300.0, 0.0, 60.0],
    "a": [0.0, 0.0, 45.0, -45.0, 0.0, 0.0, 0.0],
    "alpha": [-90.0, 90.0, -90.0, 90.0, -90.0, 90.0, 0.0],
}

ARMS = {
    "ur5": {
        "name": "UR5",
        "dh": UR5_DH,
        # The tool point the source's targets were computed with (flange frame, mm).
        "tool": [0.0, 0.09, 31.0],
        # Hayati β on the joint after each pair of parallel axes (2-3 and 3-4).
        "beta": [3, 4],
        "files": {
            "grid.csv": "serial_robots_datasets/UR5/3D_UR5_uncalibrated_grid_cleaned.csv",
            "random.csv": "serial_robots_datasets/UR5/3D_UR5_uncalibrated_random_cleaned.csv",
        },
        "limits": 360.0,
    },
    "wam": {
        "name": "WAM",
        "dh": WAM_DH,
        "tool": [0.0, 0.0, 44.0],
        "beta": [],
        "files": {
            "grid.csv": "serial_robots_datasets/WAM/3D_WAM_uncalibrated_grid_cleaned.csv",
            "random.csv": "serial_robots_datasets/WAM/3D_WAM_uncalibrated_random_cleaned.csv",
        },
        "limits": None,
    },
}


def mdh_rows(dh):
    """Modified-DH rows (alpha, a, d, theta) from a standard-DH table."""
    n = len(dh["d"])
    rows = []
    for i in range(n):
        alpha = dh["alpha"][i - 1] if i > 0 else 0.0
        a = dh["a"][i - 1] if i > 0 else 0.0
        rows.append((alpha, a, dh["d"][i], 0.0))
    if dh["a"][-1] != 0.0 or dh["alpha"][-1] != 0.0:
        raise ValueError("the last joint's a and alpha must be zero to keep the flange frame")
    return rows


def fmt(v):
    """A number as TOML and CSV write it: shortest round-trip repr, never `-0.0`."""
    v = float(v)
    if v == 0.0:
        v = 0.0
    return repr(v)


def robot_toml(arm):
    lines = [f'name = "{arm["name"]}"', ""]
    for i, (alpha, a, d, theta) in enumerate(mdh_rows(arm["dh"]), start=1):
        lines += ["[[joint]]", f"a = {fmt(a)}", f"alpha = {fmt(alpha)}", f"d = {fmt(d)}"]
        lines.append(f"theta = {fmt(theta)}")
        if i in arm["beta"]:
            lines.append("beta = 0.0")
        if arm["limits"] is not None:
            lim = arm["limits"]
            lines.append(f"limits = [{fmt(-lim)}, {fmt(lim)}]")
        lines.append("")
    lines += ["[base]", "xyz = [0.0, 0.0, 0.0]", "rpy = [0.0, 0.0, 0.0]", ""]
    lines += ["[tool]", "xyz = [" + ", ".join(fmt(t) for t in arm["tool"]) + "]", ""]
    return "\n".join(lines)


def convert_rows(path, prefix, dof):
    """The source's rows as robocal rows: pose, seq, q1..qN, load, x, y, z, x_t, y_t, z_t."""
    out = []
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        want = ["step_order", "x_t", "y_t", "z_t", "x_dif", "y_dif", "z_dif"]
        want += [f"joint_{k}" for k in range(1, dof + 1)]
        missing = [c for c in want if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"{path}: missing columns {', '.join(missing)}")
        width = len(str(sum(1 for _ in open(path)) - 1))
        for line, r in enumerate(reader, start=2):
            try:
                seq = int(r["step_order"])
                t = [float(r[c]) for c in ("x_t", "y_t", "z_t")]
                dif = [float(r[c]) for c in ("x_dif", "y_dif", "z_dif")]
                q = [float(r[f"joint_{k}"]) for k in range(1, dof + 1)]
            except ValueError as e:
                raise ValueError(f"{path}:{line}: {e}") from None
            if not all(math.isfinite(v) for v in t + dif + q):
                raise ValueError(f"{path}:{line}: a value is not finite")
            measured = [t[k] + dif[k] for k in range(3)]
            out.append([f"{prefix}{seq:0{width}d}", str(seq)] + [fmt(v) for v in q] + ["0"]
                       + [fmt(v) for v in measured] + [fmt(v) for v in t])
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("source", type=Path, help="folder holding serial_robots_datasets/")
    ap.add_argument("--out", type=Path, default=Path("datasets"))
    args = ap.parse_args()
    for key, arm in ARMS.items():
        dof = len(arm["dh"]["d"])
        folder = args.out / key
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "robot.toml").write_text(robot_toml(arm))
        header = ["pose", "seq"] + [f"q{k}" for k in range(1, dof + 1)]
        header += ["load", "x", "y", "z", "x_t", "y_t", "z_t"]
        for name, rel in arm["files"].items():
            prefix = name.split(".")[0][0]
            rows = convert_rows(args.source / rel, prefix, dof)
            with open(folder / name, "w", newline="") as f:
                w = csv.writer(f, lineterminator="\n")
                w.writerow(header)
                w.writerows(rows)
            print(f"{folder / name}: {len(rows)} rows from {rel}", file=sys.stderr)
            if name == "random.csv":
                # The test poses' targets as `compensate` reads them: the commanded joints are
                # the seed, the source's target the position to reach.
                with open(folder / "targets.csv", "w", newline="") as f:
                    w = csv.writer(f, lineterminator="\n")
                    w.writerow(["id"] + [f"q{k}" for k in range(1, dof + 1)] + ["load", "x", "y", "z"])
                    for r in rows:
                        w.writerow([r[0]] + r[2:2 + dof] + ["0"] + r[-3:])


if __name__ == "__main__":
    main()
