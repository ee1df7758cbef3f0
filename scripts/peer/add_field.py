#!/usr/bin/env python3
"""Adds an error of no physical form to exported twin cases: a probe of the residual models.

The accuracy suite's twins hold physics (geometry, compliance, gear harmonics, backlash, tilts,
runouts): even their effects beyond robocal's model family are joint-periodic terms that the
identified harmonics and runouts share a form with. A real arm holds besides whatever it holds
(cable drag, structural bending that is not a joint's, a tracker's own errors), of no form a
calibration knows. This script adds such an error to every row of a case, so that only a
residual model learned from the data can take it.

The error is a smooth random field of the joint angles (raw radians, not periodic) and the load:
a draw of a Gaussian process with a squared-exponential kernel of length `--length` radians in
every joint, by random Fourier features (`--features` of them); a fraction `--load-share` of it
grows with the load (times load / the largest load of the case's rows). Each world axis has its
own draw. The field is scaled so that its mean length over the case's training rows is
`--amplitude` mm, and added to the measured points of `train.csv` and `test.csv` and to the
noise-free points of `truth.csv` alike (the tracker noise stays as it was).

    python scripts/peer/add_field.py IN_CASES OUT_CASES [--amplitude 0.1] [--length 1.0]
        [--load-share 0.3] [--features 400] [--seed 0] [--only SUBSTR]

Every case directory of IN_CASES (holding `robot.toml`, `train.csv`, `test.csv`, `truth.csv`)
is written to OUT_CASES under the same name, `robot.toml` copied; the field's draw depends on
`--seed` and the case's joint count only, so every case of one arm gets the same field.
"""

from __future__ import annotations

import argparse
import csv
import shutil
import sys
from pathlib import Path

import numpy as np


def read(path: Path) -> tuple[list[str], list[list[str]]]:
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def write(path: Path, header: list[str], rows: list[list[str]]) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(header)
        w.writerows(rows)


class Field:
    """A smooth random vector field of the joint angles (rad) and the load (kg), in mm."""

    def __init__(self, joints: int, args: argparse.Namespace):
        rng = np.random.default_rng([args.seed, joints])
        m = args.features
        # Two draws per axis: one that does not depend on the load, one that grows with it.
        self.freq = rng.normal(0.0, 1.0 / args.length, size=(2, 3, m, joints))
        self.phase = rng.uniform(0.0, 2.0 * np.pi, size=(2, 3, m))
        self.weight = rng.normal(0.0, 1.0, size=(2, 3, m)) * np.sqrt(2.0 / m)
        self.share = args.load_share
        self.scale = 1.0
        self.max_load = 1.0

    def raw(self, q: np.ndarray, load: np.ndarray) -> np.ndarray:
        """(rows, 3) before scaling: q (rows, joints) rad, load (rows,) kg."""
        # (2, 3, m, rows): every feature at every row.
        arg = np.einsum("pamj,rj->pamr", self.freq, q) + self.phase[..., None]
        draws = np.einsum("pam,pamr->par", self.weight, np.cos(arg))
        fixed, loaded = draws[0], draws[1]
        grow = load / self.max_load
        return ((1.0 - self.share) * fixed + self.share * loaded * grow).T

    def __call__(self, q: np.ndarray, load: np.ndarray) -> np.ndarray:
        return self.scale * self.raw(q, load)


def columns(header: list[str]) -> tuple[list[int], int | None, list[int]]:
    joints = [i for i, h in enumerate(header) if h.startswith("q") and h[1:].isdigit()]
    load = header.index("load") if "load" in header else None
    xyz = [header.index(c) for c in ("x", "y", "z")]
    return joints, load, xyz


def inputs(header: list[str], rows: list[list[str]]) -> tuple[np.ndarray, np.ndarray]:
    joints, load, _ = columns(header)
    q = np.radians(np.array([[float(r[i]) for i in joints] for r in rows]))
    w = np.array([float(r[load]) if load is not None else 0.0 for r in rows])
    return q, w


def shifted(header: list[str], rows: list[list[str]], field: Field) -> list[list[str]]:
    _, _, xyz = columns(header)
    q, w = inputs(header, rows)
    d = field(q, w)
    out = []
    for r, dr in zip(rows, d):
        r = list(r)
        for k, i in enumerate(xyz):
            r[i] = f"{float(r[i]) + dr[k]:.6f}"
        out.append(r)
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("cases", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument("--amplitude", type=float, default=0.1, help="mean length on train, mm")
    p.add_argument("--length", type=float, default=1.0, help="length scale, rad")
    p.add_argument("--load-share", type=float, default=0.3)
    p.add_argument("--features", type=int, default=400)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--only", default="")
    args = p.parse_args()
    cases = sorted(d for d in args.cases.iterdir() if (d / "train.csv").is_file())
    cases = [d for d in cases if args.only in d.name]
    if not cases:
        print(f"no case directories in {args.cases}", file=sys.stderr)
        return 1
    for case in cases:
        header, train = read(case / "train.csv")
        joints, _, _ = columns(header)
        field = Field(len(joints), args)
        q, w = inputs(header, train)
        field.max_load = max(float(w.max()), 1e-9) if len(w) else 1.0
        mean = float(np.linalg.norm(field.raw(q, w), axis=1).mean())
        field.scale = args.amplitude / mean
        out = args.out / case.name
        out.mkdir(parents=True, exist_ok=True)
        shutil.copy(case / "robot.toml", out / "robot.toml")
        for name in ("train.csv", "test.csv", "truth.csv"):
            h, rows = read(case / name)
            write(out / name, h, shifted(h, rows, field))
        th, trows = read(case / "test.csv")
        tq, tw = inputs(th, trows)
        on_test = float(np.linalg.norm(field(tq, tw), axis=1).mean())
        print(f"{case.name}: field mean {args.amplitude:.4f} mm on train, {on_test:.4f} on test")
    return 0


if __name__ == "__main__":
    sys.exit(main())
