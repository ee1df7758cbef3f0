#!/usr/bin/env python3
"""Convert the open laser-tracker datasets into robocal's measurement format.

Reads the source files as published (a copy lies in ../shared/data of the development machines)
and writes, for each arm, `robot.toml` (the maker's published nominal table as modified DH), one
measurement CSV per source file, and `targets.csv` (the test poses' targets for `robocal
compensate`); the README and licence notice of each folder are written by hand.

  python3 scripts/datasets/convert.py SOURCE_DIR [--out datasets]

SOURCE_DIR holds `serial_robots_datasets/` (UR5 and WAM, P. Jacobi, MIT licence) and
`ipa-robot-accuracy/` (UR10 with a T-Mac 6-DoF probe, C. Landgraf et al., MIT licence).

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

UR10 rows: the probe's measured position (mm) and orientation (`measurement_rx, ry, rz`, deg,
intrinsic X-Y-Z Euler angles: R = Rx(rx) Ry(ry) Rz(rz)) in the tracker frame of its series, the
joint angles (rad, written in deg) and the commanded pose (`Goal x, y, z` m, `Goal roll, pitch,
yaw` rad, fixed-axis x-y-z, robot base frame). The orientation is written in robocal's convention
(fixed-axis roll, pitch, yaw: R = Rz(rz) Ry(ry) Rx(rx)), the source's angles kept beside it
(`tmac_rx, tmac_ry, tmac_rz`) for the round-trip test; the goal in mm and deg (`goal_*`); the
per-value standard deviations (`std_x` … `std_rz`) and the temperature (`temperature`, °C). The
probe's frame in the flange frame is the inverse of the source's `Trafo_TM_F_init.txt`; UR's base
frame is the DH base turned 180° about z.
"""

import argparse
import csv
import math
import sys
from pathlib import Path

UR10_DH = {
    "d": [127.3, 0.0, 0.0, 163.941, 115.7, 92.2],
    "a": [0.0, -612.0, -572.3, 0.0, 0.0, 0.0],
    "alpha": [90.0, 0.0, 0.0, 90.0, -90.0, 0.0],
}

# Series of the UR10: output file, source file, pose-id prefix.
UR10_SERIES = [
    ("series-a-grid.csv", "Series_A/measurements_grid.csv", "a"),
    ("series-b-joint-configurations.csv", "Series_B/measurements_joint_configurations.csv", "b"),
    ("series-c-random.csv", "Series_C/measurements_random_poses.csv", "c"),
    ("series-d-iso-cubes.csv", "Series_D/measurements_iso_cubes.csv", "d"),
]

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


def mat_mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(len(b))) for j in range(len(b[0]))]
            for i in range(len(a))]


def rot_x(t):
    c, s_ = math.cos(t), math.sin(t)
    return [[1.0, 0.0, 0.0], [0.0, c, -s_], [0.0, s_, c]]


def rot_y(t):
    c, s_ = math.cos(t), math.sin(t)
    return [[c, 0.0, s_], [0.0, 1.0, 0.0], [-s_, 0.0, c]]


def rot_z(t):
    c, s_ = math.cos(t), math.sin(t)
    return [[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]]


def intrinsic_xyz(rx, ry, rz):
    """R = Rx(rx) Ry(ry) Rz(rz), angles in deg (the T-Mac's Euler angles)."""
    r = [math.radians(v) for v in (rx, ry, rz)]
    return mat_mul(mat_mul(rot_x(r[0]), rot_y(r[1])), rot_z(r[2]))


def fixed_xyz_angles(m):
    """robocal's (roll, pitch, yaw), deg, of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    pitch = math.asin(max(-1.0, min(1.0, -m[2][0])))
    roll = math.atan2(m[2][1], m[2][2])
    yaw = math.atan2(m[1][0], m[0][0])
    return [math.degrees(v) for v in (roll, pitch, yaw)]


def invert_rigid(m):
    """The inverse of a 4x4 rigid transform."""
    r = [[m[j][i] for j in range(3)] for i in range(3)]
    t = [-sum(r[i][k] * m[k][3] for k in range(3)) for i in range(3)]
    return [r[0] + [t[0]], r[1] + [t[1]], r[2] + [t[2]], [0.0, 0.0, 0.0, 1.0]]


def decimal(text, where):
    """A number written with `,` as the decimal mark."""
    try:
        v = float(text.replace(",", "."))
    except ValueError:
        raise ValueError(f"{where}: `{text}` is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"{where}: `{text}` is not finite")
    return v


def ur10_robot(probe):
    """The UR10's robot.toml: UR's table as MDH, the base turned 180° about z, the probe's
    frame (its origin and axes in the flange frame) as the tool."""
    rows = mdh_rows(UR10_DH)
    lines = ['name = "UR10"', ""]
    for i, (alpha, a, d, theta) in enumerate(rows, start=1):
        lines += ["[[joint]]", f"a = {fmt(a)}", f"alpha = {fmt(alpha)}", f"d = {fmt(d)}",
                  f"theta = {fmt(theta)}"]
        if i in (3, 4):
            lines.append("beta = 0.0")
        lines += ["limits = [-360.0, 360.0]", ""]
    rpy = fixed_xyz_angles([row[:3] for row in probe[:3]])
    xyz = [probe[i][3] for i in range(3)]
    lines += ["[base]", "xyz = [0.0, 0.0, 0.0]", "rpy = [0.0, 0.0, 180.0]", ""]
    lines += ["[tool]", "xyz = [" + ", ".join(fmt(round(v, 9)) for v in xyz) + "]",
              "rpy = [" + ", ".join(fmt(round(v, 9)) for v in rpy) + "]", ""]
    return "\n".join(lines)


UR10_COLUMNS = ["pose", "seq", "q1", "q2", "q3", "q4", "q5", "q6", "load", "x", "y", "z",
                "rx", "ry", "rz", "temperature", "std_x", "std_y", "std_z", "std_rx", "std_ry",
                "std_rz", "tmac_rx", "tmac_ry", "tmac_rz", "goal_x", "goal_y", "goal_z",
                "goal_roll", "goal_pitch", "goal_yaw"]


def convert_ur10(path, prefix):
    """The source's rows of one series as robocal rows (`UR10_COLUMNS`)."""
    out = []
    with open(path, newline="") as f:
        reader = csv.DictReader(f, delimiter=";")
        joints = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
                  "wrist_2_joint", "wrist_3_joint"]
        need = ["Goal x", "Goal y", "Goal z", "Goal roll", "Goal pitch", "Goal yaw",
                "measurement_temperature", "measurement_x", "measurement_y", "measurement_z",
                "measurement_rx", "measurement_ry", "measurement_rz"] + joints
        missing = [c for c in need if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"{path}: missing columns {', '.join(missing)}")
        rows = list(reader)
        width = len(str(len(rows)))
        for n, r in enumerate(rows):
            where = f"{path}:{n + 2}"
            get = lambda c: decimal(r[c], f"{where}: {c}")  # noqa: E731
            std = lambda c: fmt(get(c)) if r.get(c, "") != "" else ""  # noqa: E731
            q = [math.degrees(get(c)) for c in joints]
            tmac = [get(c) for c in ("measurement_rx", "measurement_ry", "measurement_rz")]
            rpy = fixed_xyz_angles(intrinsic_xyz(*tmac))
            goal = [1000.0 * get(c) for c in ("Goal x", "Goal y", "Goal z")]
            goal_rpy = [math.degrees(get(c)) for c in ("Goal roll", "Goal pitch", "Goal yaw")]
            out.append(
                [f"{prefix}{n:0{width}d}", str(n)] + [fmt(v) for v in q] + ["0"]
                + [fmt(get(c)) for c in ("measurement_x", "measurement_y", "measurement_z")]
                + [fmt(v) for v in rpy] + [fmt(get("measurement_temperature"))]
                + [std(f"measurement_std_{c}") for c in ("x", "y", "z", "rx", "ry", "rz")]
                + [fmt(v) for v in tmac] + [fmt(v) for v in goal] + [fmt(v) for v in goal_rpy])
    return out


def write_ur10(source, out):
    folder = out / "ur10-tmac"
    folder.mkdir(parents=True, exist_ok=True)
    base = source / "ipa-robot-accuracy"
    text = (base / "Series_A" / "Trafo_TM_F_init.txt").read_text().split()
    trafo = [[float(v) for v in text[4 * i:4 * i + 4]] for i in range(4)]
    (folder / "robot.toml").write_text(ur10_robot(invert_rigid(trafo)))
    for name, rel, prefix in UR10_SERIES:
        rows = convert_ur10(base / rel, prefix)
        with open(folder / name, "w", newline="") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(UR10_COLUMNS)
            w.writerows(rows)
        print(f"{folder / name}: {len(rows)} rows from {rel}", file=sys.stderr)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("source", type=Path, help="folder holding serial_robots_datasets/")
    ap.add_argument("--out", type=Path, default=Path("datasets"))
    args = ap.parse_args()
    write_ur10(args.source, args.out)
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
