"""The Python bindings against the command line on the same files, and their errors.

The `robocal` binary is taken from $ROBOCAL_BIN, else target/debug or target/release of the
repository (`cargo build` makes it); the tests fail, never skip, without it.
"""

import csv
import json
import os
import subprocess
import sys
import threading
import tomllib
from pathlib import Path

import numpy as np
import pytest

import robocal

ROOT = Path(__file__).resolve().parents[3]
ROBOT = ROOT / "configs/robots/pmc6va030.toml"
DATA = ROOT / "datasets/pmc6va030/measurements.csv"
STAGES = ROOT / "configs/stages"


def binary():
    given = os.environ.get("ROBOCAL_BIN")
    if given:
        return given
    for profile in ("debug", "release"):
        path = ROOT / "target" / profile / "robocal"
        if path.exists():
            return str(path)
    raise RuntimeError("no robocal binary: run `cargo build` or set ROBOCAL_BIN")


def cli(*args):
    done = subprocess.run(
        [binary(), *map(str, args)], cwd=ROOT, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    return done


def rows(keep):
    """The bundled twin's rows whose pose index (0-based, file order) and load `keep` accepts."""
    with open(DATA, newline="") as f:
        all_rows = list(csv.DictReader(f))
    order = list(dict.fromkeys(r["pose"] for r in all_rows))
    index = {p: i for i, p in enumerate(order)}
    return [r for r in all_rows if keep(index[r["pose"]], float(r["load"]))]


def arrays(selected):
    q = np.array([[float(r[f"q{k}"]) for k in range(1, 7)] for r in selected])
    load = np.array([float(r["load"]) for r in selected])
    xyz = np.array([[float(r[a]) for a in "xyz"] for r in selected])
    return q, load, xyz, [r["pose"] for r in selected]


def write_csv(path, selected):
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(selected[0].keys()))
        w.writeheader()
        w.writerows(selected)
    return path


TRAIN = rows(lambda c, l: c < 48 and l in (0.0, 10.0, 20.0))
TEST = rows(lambda c, l: c >= 150 and l in (0.0, 5.0, 15.0))


def predicted_csv(path):
    with open(path, newline="") as f:
        return np.array([[float(r[a]) for a in "xyz"] for r in csv.DictReader(f)])


def test_robot_from_a_file_and_from_arrays_give_the_cli_s_points(tmp_path):
    robot = robocal.Robot.load(ROBOT)
    assert robot.dof == 6 and robot.name == "PMC6VA030"
    q, load, _, _ = arrays(TEST)
    out = tmp_path / "nominal.csv"
    cli("predict", "--robot", ROBOT, "--data", write_csv(tmp_path / "t.csv", TEST), "--out", out)
    np.testing.assert_allclose(robot.forward(q), predicted_csv(out), atol=1e-6, rtol=0)
    table = tomllib.loads(ROBOT.read_text())
    joints = table["joint"]
    built = robocal.Robot(
        [[j["a"], j["alpha"], j["d"], j["theta"]] for j in joints],
        beta=[j.get("beta", np.nan) for j in joints],
        limits=[j["limits"] for j in joints],
        base_xyz=table["base"]["xyz"],
        base_rpy=table["base"]["rpy"],
        tool=table["tool"]["xyz"],
        name="built",
    )
    np.testing.assert_allclose(built.forward(q), robot.forward(q), atol=1e-9, rtol=0)


PLANAR_URDF = """<robot name="planar">
<link name="base"/><link name="upper"/><link name="fore"/><link name="hand"/>
<joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
<origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/>
<limit lower="-1.5" upper="1.5" effort="1" velocity="1"/></joint>
<joint name="elbow" type="continuous"><parent link="upper"/><child link="fore"/>
<origin xyz="0.3 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/></joint>
<joint name="wrist" type="fixed"><parent link="fore"/><child link="hand"/>
<origin xyz="0.2 0 0" rpy="0 0 0"/></joint>
</robot>
"""


def test_a_urdf_and_a_dh_table_import_as_the_cli_s(tmp_path):
    urdf = tmp_path / "planar.urdf"
    urdf.write_text(PLANAR_URDF)
    dh = tmp_path / "planar.csv"
    dh.write_text("d,a,alpha,theta\n0,300,0,0\n0,200,0,0\n")
    q = np.array([[10.0, 20.0], [-35.0, 80.0], [0.0, 0.0]])
    r1, r12 = np.radians(q[:, 0]), np.radians(q[:, 0] + q[:, 1])
    # Two links of 300 and 200 mm turning about z: the hand at their sum.
    expected = np.stack([300 * np.cos(r1) + 200 * np.cos(r12), 300 * np.sin(r1) + 200 * np.sin(r12), 0 * r1], axis=1)
    for robot in (robocal.Robot.from_urdf(urdf), robocal.Robot.from_dh(dh, "standard")):
        np.testing.assert_allclose(robot.forward(q), expected, atol=1e-9, rtol=0)
    tooled = robocal.Robot.from_urdf(urdf, tip="fore", tool=[200.0, 0.0, 0.0])
    np.testing.assert_allclose(tooled.forward(q), expected, atol=1e-9, rtol=0)
    out = tmp_path / "planar.toml"
    cli("import", "--urdf", urdf, "--out", out)
    np.testing.assert_allclose(robocal.Robot.load(out).forward(q), expected, atol=1e-9, rtol=0)
    with pytest.raises(robocal.RobocalError, match="convention"):
        robocal.Robot.from_dh(dh, "distal")
    with pytest.raises(robocal.RobocalError, match="`nowhere` is no link"):
        robocal.Robot.from_urdf(urdf, tip="nowhere")


@pytest.mark.parametrize("config", [None, "compliance.toml", "gp.toml"])
def test_calibrate_equals_the_cli_on_the_same_rows(tmp_path, config):
    train = write_csv(tmp_path / "train.csv", TRAIN)
    test = write_csv(tmp_path / "test.csv", TEST)
    model_dir = tmp_path / "cli-model"
    extra = ["--config", STAGES / config] if config else []
    printed = cli(
        "calibrate", "--robot", ROBOT, "--data", train, "--out", model_dir, *extra
    ).stdout
    out = tmp_path / "pred.csv"
    cli("predict", "--model", model_dir, "--data", test, "--out", out)

    q, load, xyz, pose = arrays(TRAIN)
    model = robocal.calibrate(
        robocal.Robot.load(ROBOT),
        q,
        load,
        xyz,
        config=STAGES / config if config else None,
        pose=pose,
    )
    tq, tload, txyz, _ = arrays(TEST)
    mine = model.predict(tq, tload)
    # The CLI's file holds 6 decimals.
    np.testing.assert_allclose(mine, predicted_csv(out), atol=2e-6, rtol=0)
    # The same model: loaded from the CLI's directory, it predicts what Python's does.
    np.testing.assert_allclose(
        robocal.Model.load(model_dir).predict(tq, tload), mine, atol=1e-9, rtol=0
    )
    stats = model.evaluate(tq, tload, txyz)
    evaluated = json.loads(
        cli("evaluate", "--model", model_dir, "--data", test, "--json").stdout
    )
    for key in ("count", "mean", "max"):
        assert stats[key] == pytest.approx(evaluated[key], abs=1e-6)
    report = json.loads(model.report)
    assert report["kinematic"]["after"]["mean"] < report["kinematic"]["before"]["mean"]
    # The summary the command line ends with, but for the time and where the files are.
    timeless = lambda text: [  # noqa: E731
        line
        for line in text.splitlines()
        if not line.startswith(("  time ", "  files "))
    ]
    assert model.summary.startswith("calibration summary\n")
    assert timeless(model.summary) == timeless(printed)
    assert robocal.Model.load(model_dir).summary is None


def test_a_budget_kept_by_counted_work_says_so_and_far_under_it_changes_nothing():
    q, load, xyz, pose = arrays(TRAIN)
    robot = robocal.Robot.load(ROBOT)
    by_clock = robocal.calibrate(robot, q, load, xyz, pose=pose)
    counted = robocal.calibrate(robot, q, load, xyz, pose=pose, reproducible=True)
    selection = json.loads(counted.report)["selection"]
    assert selection["reproducible"] is True
    assert 0.0 < selection["counted_seconds"] <= selection["budget_seconds"]
    assert json.loads(by_clock.report)["selection"]["reproducible"] is False
    tq, tload, _, _ = arrays(TEST)
    np.testing.assert_allclose(
        counted.predict(tq, tload), by_clock.predict(tq, tload), atol=0, rtol=0
    )


def test_a_saved_model_reloads_and_the_cli_reads_it(tmp_path):
    q, load, xyz, _ = arrays(TRAIN)
    model = robocal.calibrate(
        robocal.Robot.load(ROBOT), q, load, xyz, config=STAGES / "gp.toml"
    )
    out = tmp_path / "py-model"
    model.save(out)
    back = robocal.Model.load(out)
    tq, tload, txyz, _ = arrays(TEST)
    p0, s0 = model.predict(tq, tload, sigma=True)
    p1, s1 = back.predict(tq, tload, sigma=True)
    np.testing.assert_array_equal(p0, p1)
    np.testing.assert_array_equal(s0, s1)
    assert (s0 > 0).all()
    evaluated = json.loads(
        cli(
            "evaluate", "--model", out, "--data", write_csv(tmp_path / "t.csv", TEST), "--json"
        ).stdout
    )
    assert evaluated["mean"] == pytest.approx(model.evaluate(tq, tload, txyz)["mean"], abs=1e-9)
    # One number for every row's load.
    np.testing.assert_array_equal(model.predict(tq, 5.0), model.predict(tq, np.full(len(tq), 5.0)))
    # A physical model gives its parameters' deviations, and keeps them through its directory;
    # one read from a directory without its covariance gives none.
    plain = robocal.calibrate(
        robocal.Robot.load(ROBOT), q, load, xyz, config=STAGES / "kinematic-lm.toml"
    )
    p2, s2 = plain.predict(tq, tload, sigma=True)
    assert s2.shape == (len(tq),) and (s2 > 0).all() and np.isfinite(s2).all()
    plain_dir = tmp_path / "plain"
    plain.save(plain_dir)
    np.testing.assert_array_equal(robocal.Model.load(plain_dir).predict(tq, tload, sigma=True)[1], s2)
    (plain_dir / "covariance.json").unlink()
    with pytest.raises(robocal.RobocalError, match="no standard deviation"):
        robocal.Model.load(plain_dir).predict(tq, tload, sigma=True)


def test_compensation_reaches_the_targets_and_equals_the_cli(tmp_path):
    q, load, xyz, _ = arrays(TRAIN)
    model = robocal.calibrate(
        robocal.Robot.load(ROBOT), q, load, xyz, config=STAGES / "compliance.toml"
    )
    model_dir = tmp_path / "m"
    model.save(model_dir)
    tq, tload, _, _ = arrays(TEST[:12])
    targets = model.predict(tq, tload)
    seed = tq + 0.5
    commands, error = model.compensate(targets, seed, tload)
    # Three coordinates of six joints: the commands put the model's point on the target (the
    # seed's orientation kept), near the seed, within compensation's tolerance (1e-3 mm).
    reached = np.linalg.norm(model.predict(commands, tload) - targets, axis=1)
    np.testing.assert_allclose(reached, error, atol=1e-9, rtol=0)
    assert (error < 1e-3).all() and np.abs(commands - seed).max() < 10.0
    # The CLI on the same targets.
    path = tmp_path / "targets.csv"
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["id", *[f"q{k}" for k in range(1, 7)], "load", "x", "y", "z"])
        for i in range(len(tq)):
            w.writerow([f"t{i}", *seed[i], tload[i], *targets[i]])
    out = tmp_path / "commands.csv"
    cli("compensate", "--model", model_dir, "--targets", path, "--out", out)
    with open(out, newline="") as f:
        theirs = np.array([[float(r[f"q{k}"]) for k in range(1, 7)] for r in csv.DictReader(f)])
    np.testing.assert_allclose(commands, theirs, atol=2e-6, rtol=0)
    # Out of reach: NaN and a warning naming the row.
    with pytest.warns(Warning, match="row 1"):
        far, _ = model.compensate([[1e5, 0.0, 0.0]], seed[:1], 0.0)
    assert np.isnan(far).all()


def test_errors_carry_the_cli_s_messages():
    robot = robocal.Robot.load(ROBOT)
    q, load, xyz, _ = arrays(TRAIN)
    bad_q = q.copy()
    bad_q[2, 1] = np.nan
    with pytest.raises(robocal.RobocalError, match=r"line 3, column `q2`: `NaN` is not a finite"):
        robocal.calibrate(robot, bad_q, load, xyz)
    bad_load = load.copy()
    bad_load[4] = -1.0
    with pytest.raises(robocal.RobocalError, match=r"line 5, column `load`: negative load"):
        robocal.calibrate(robot, q, bad_load, xyz)
    with pytest.raises(robocal.RobocalError, match="xyz: 2 columns"):
        robocal.calibrate(robot, q, load, xyz[:, :2])
    with pytest.raises(robocal.RobocalError, match="q: 5 columns, a robot with 6 joints"):
        robot.forward(q[:, :5])
    with pytest.raises(robocal.RobocalError, match="no-such.toml"):
        robocal.Robot.load(ROOT / "no-such.toml")
    with pytest.raises(robocal.RobocalError, match="model directory not found"):
        robocal.Model.load(ROOT / "no-such-model")
    with pytest.raises(robocal.RobocalError, match="key `joint\\[1\\].alpha`"):
        robocal.Robot([[0.0, np.inf, 0.0, 0.0]])
    # Data in metres: refused unless forced, as the CLI does.
    with pytest.raises(robocal.RobocalError, match="nothing written"):
        robocal.calibrate(robot, q, load, xyz / 1000.0)
    # The default calibration's time budget: positive seconds, not with a stage config.
    with pytest.raises(robocal.RobocalError, match="0 is not a positive number of seconds"):
        robocal.calibrate(robot, q, load, xyz, budget=0.0)
    with pytest.raises(robocal.RobocalError, match="takes none"):
        robocal.calibrate(robot, q, load, xyz, budget=60.0, config=ROOT / "configs/stages/kinematic-lm.toml")
    # The bearings' tilt is the default's to try; a stage config asks for it in [joint_errors].
    with pytest.raises(robocal.RobocalError, match="tilt = true"):
        robocal.calibrate(robot, q, load, xyz, tilt=True, config=ROOT / "configs/stages/kinematic-lm.toml")
    # So is backlash added with its flanks searched.
    with pytest.raises(robocal.RobocalError, match="flank_search = true"):
        robocal.calibrate(robot, q, load, xyz, flank_search=True, config=ROOT / "configs/stages/kinematic-lm.toml")
    # So is the frame the residual models learn in; and it is one of two.
    with pytest.raises(robocal.RobocalError, match='frame = "joint1"'):
        robocal.calibrate(robot, q, load, xyz, residual_frame="joint1", config=ROOT / "configs/stages/kinematic-lm.toml")
    with pytest.raises(robocal.RobocalError, match="`tool` is not a frame"):
        robocal.calibrate(robot, q, load, xyz, residual_frame="tool")
    # The options are the command line's and a stage file's [default]: a misspelt one is named.
    with pytest.raises(robocal.RobocalError, match="unknown field `budgett`"):
        robocal.calibrate(robot, q, load, xyz, budgett=30.0)
    # numpy's numbers reach the same checks as Python's.
    with pytest.raises(robocal.RobocalError, match="--runout: 40 orders"):
        robocal.calibrate(robot, q, load, xyz, runout=np.int64(40))
    with pytest.raises(robocal.RobocalError, match="0 is not a positive number of seconds"):
        robocal.calibrate(robot, q, load, xyz, budget=np.float64(0.0))
    # RobocalError is a ValueError.
    assert issubclass(robocal.RobocalError, ValueError)


def test_calibration_releases_the_interpreter():
    q, load, xyz, pose = arrays(TRAIN)
    robot = robocal.Robot.load(ROBOT)
    done = []
    worker = threading.Thread(
        target=lambda: done.append(robocal.calibrate(robot, q, load, xyz, pose=pose))
    )
    ticks = 0
    worker.start()
    while worker.is_alive():
        ticks += 1
        worker.join(0.001)
    assert done and ticks > 20, ticks


def test_write_report_draws_the_pictures(tmp_path):
    q, load, xyz, _ = arrays(TRAIN)
    model = robocal.calibrate(
        robocal.Robot.load(ROBOT), q, load, xyz, config=STAGES / "compliance.toml"
    )
    tq, tload, txyz, _ = arrays(TEST)
    stats = json.loads(model.write_report(tq, tload, txyz, tmp_path / "report"))
    assert stats["before"]["mean"] > stats["after"]["mean"]
    for stem in ("histogram", "per-pose", "axes-joints", "load", "workspace"):
        assert (tmp_path / "report" / f"{stem}.png").exists()
    assert (tmp_path / "report" / "report.html").exists()


def test_the_readme_example_runs_and_prints_a_held_out_error():
    text = (ROOT / "README.md").read_text()
    example = text.split("```python\n", 1)[1].split("```", 1)[0]
    done = subprocess.run(
        [sys.executable, "-c", example], cwd=ROOT, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    printed = done.stdout
    assert printed.startswith("Model(6 joints") and "'mean': 0." in printed, printed


def reflector_twin(tmp_path):
    """The bundled twin measuring three reflectors at 30 configurations, 0 and 20 kg."""
    text = (ROOT / "configs/twin/pmc6va030.toml").read_text()
    text = text.replace(
        'nominal = "../robots/pmc6va030.toml"', f'nominal = "{ROBOT}"'
    ).replace("count = 168", "count = 30")
    text = text.replace(
        "[truth.tool]\nxyz = [2.14, -1.37, 98.26]\n",
        "[truth.tool]\nxyz = [2.14, -1.37, 98.26]\n\n[truth.tool.points]\n"
        "smr2 = [83.1, 1.2, 62.0]\nsmr3 = [-37.0, 71.5, 63.1]\n",
    )
    lines = text.splitlines()
    lines = [
        "trained = [0.0, 20.0]" if l.startswith("trained = [") else
        "untrained = []" if l.startswith("untrained = [") else l
        for l in lines
    ]
    twin = tmp_path / "twin.toml"
    twin.write_text("\n".join(lines) + "\n")
    cli("simulate", "--twin", twin, "--out", tmp_path / "data")
    with open(tmp_path / "data/measurements.csv", newline="") as f:
        measured = list(csv.DictReader(f))
    robot = tmp_path / "robot.toml"
    robot.write_text(
        ROBOT.read_text()
        + "\n[tool.points]\nsmr2 = [80.0, 0.0, 60.0]\nsmr3 = [-40.0, 70.0, 60.0]\n"
    )
    return robot, tmp_path / "data/measurements.csv", measured


def test_several_reflectors_equal_the_cli(tmp_path):
    robot_file, data, measured = reflector_twin(tmp_path)
    q, load, xyz, pose = arrays(measured)
    target = [r["target"] for r in measured]
    assert set(target) == {"", "smr2", "smr3"}
    stage = STAGES / "kinematic-lm.toml"
    model_dir = tmp_path / "cli-model"
    cli("calibrate", "--robot", robot_file, "--data", data, "--out", model_dir, "--config", stage)
    out = tmp_path / "pred.csv"
    cli("predict", "--model", model_dir, "--data", data, "--out", out)
    with open(out, newline="") as f:
        predicted = list(csv.DictReader(f))
    assert [r["target"] for r in predicted] == target
    theirs = np.array([[float(r[a]) for a in "xyz"] for r in predicted])

    robot = robocal.Robot.load(robot_file)
    model = robocal.calibrate(robot, q, load, xyz, config=stage, pose=pose, target=target)
    mine = model.predict(q, load, target=target)
    np.testing.assert_allclose(mine, theirs, atol=2e-6, rtol=0)
    # The points differ as the plate does; the identified table carries them.
    assert np.linalg.norm(mine[1] - mine[0]) > 50.0
    assert "[tool.points]" in model.robot.to_toml()
    # Built from arrays with the same points: the same forward kinematics per target.
    built = robocal.Robot(
        [[0.0, 0.0, 0.0, 0.0]], points={"smr2": [1.0, 2.0, 3.0]}, tool=[0.0, 0.0, 5.0]
    )
    np.testing.assert_allclose(built.forward([[0.0]], "smr2"), [[1.0, 2.0, 3.0]])
    with pytest.raises(robocal.RobocalError, match="column `target`: no point `smr9`"):
        model.predict(q[:2], load[:2], target=["", "smr9"])
    # Compensation puts each row's named point on its target.
    rows = [i for i, t in enumerate(target) if t == "smr3"][:4]
    goals = mine[rows]
    commands, error = model.compensate(goals, q[rows] + 0.5, load[rows], target=["smr3"] * 4)
    reached = model.predict(commands, load[rows], target=["smr3"] * 4)
    assert np.linalg.norm(reached - goals, axis=1).max() < 2e-3 and (error < 1e-3).all()
    with pytest.raises(robocal.RobocalError, match="target: 1 names for 2 rows"):
        model.predict(q[:2], load[:2], target=[""])


def test_a_6dof_probe_equals_the_cli(tmp_path):
    """A probe twin (its truth's `[tool] rpy`): `rpy=` rows calibrate as the CLI's rx, ry, rz
    columns do; `Model.orientation` gives predict's rx, ry, rz; `evaluate(rpy=)` the angles."""
    text = (ROOT / "configs/twin/pmc6va030.toml").read_text()
    text = text.replace(
        'nominal = "../robots/pmc6va030.toml"', f'nominal = "{ROBOT}"'
    ).replace("count = 168", "count = 30")
    text = text.replace(
        "[truth.tool]\nxyz = [2.14, -1.37, 98.26]\n",
        "[truth.tool]\nxyz = [2.14, -1.37, 98.26]\nrpy = [0.4, -0.3, 30.2]\n",
    )
    twin = tmp_path / "twin.toml"
    twin.write_text(text)
    cli("simulate", "--twin", twin, "--out", tmp_path / "data")
    data = tmp_path / "data/measurements.csv"
    with open(data, newline="") as f:
        measured = [r for r in csv.DictReader(f) if float(r["load"]) in (0.0, 20.0)]
    data = write_csv(tmp_path / "m.csv", measured)
    robot_file = tmp_path / "robot.toml"
    robot_file.write_text(ROBOT.read_text().replace("[tool]\n", "[tool]\nrpy = [0.0, 0.0, 30.0]\n"))
    stage = STAGES / "kinematic-lm.toml"
    model_dir = tmp_path / "cli-model"
    cli("calibrate", "--robot", robot_file, "--data", data, "--out", model_dir, "--config", stage)
    out = tmp_path / "pred.csv"
    cli("predict", "--model", model_dir, "--data", data, "--out", out)
    with open(out, newline="") as f:
        predicted = list(csv.DictReader(f))
    theirs = np.array([[float(r[a]) for a in ("rx", "ry", "rz")] for r in predicted])

    q, load, xyz, pose = arrays(measured)
    rpy = np.array([[float(r[a]) for a in ("rx", "ry", "rz")] for r in measured])
    robot = robocal.Robot.load(robot_file)
    model = robocal.calibrate(robot, q, load, xyz, config=stage, pose=pose, rpy=rpy)
    np.testing.assert_allclose(model.orientation(q, load), theirs, atol=2e-6, rtol=0)
    stats = model.evaluate(q, load, xyz, rpy=rpy)
    assert 0.005 < stats["orientation_deg"]["mean"] < 0.2, stats
    # The kinematic stage fits the unloaded rows: one orientation per configuration.
    assert json.loads(model.report)["kinematic"]["orientation"]["rows"] == len(set(pose))
    # Built from arrays: the probe's frame turns the tool frame, not the point.
    built = robocal.Robot([[0.0, 0.0, 0.0, 0.0]], tool=[0.0, 0.0, 5.0], tool_rpy=[0.0, 0.0, 30.0])
    assert "rpy = [0.0, 0.0, 30.0]" in built.to_toml()
    bad = rpy.copy()
    bad[1, 1] = 95.0
    with pytest.raises(robocal.RobocalError, match=r"line 2, column `ry`: 95 deg is out of range"):
        robocal.calibrate(robot, q, load, xyz, config=stage, pose=pose, rpy=bad)


def test_rows_outside_the_calibrated_domain_are_warned_of(tmp_path):
    import warnings

    q, load, xyz, _ = arrays(TRAIN)
    model = robocal.calibrate(
        robocal.Robot.load(ROBOT), q, load, xyz, config=STAGES / "kinematic-lm.toml"
    )
    joints, loads = model.domain
    np.testing.assert_array_equal(np.array(joints), np.stack([q.min(0), q.max(0)], axis=1))
    assert list(loads) == [load.min(), load.max()]
    # The saved directory keeps it; the CLI's calibrate on the same rows writes the same.
    model.save(tmp_path / "py")
    assert robocal.Model.load(tmp_path / "py").domain == model.domain
    cli(
        "calibrate", "--robot", ROBOT, "--data", write_csv(tmp_path / "train.csv", TRAIN),
        "--out", tmp_path / "cli", "--config", STAGES / "kinematic-lm.toml",
    )
    assert robocal.Model.load(tmp_path / "cli").domain == model.domain
    # Inside: no warning from predict, evaluate or compensate.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model.predict(q, load)
        model.evaluate(q, load, xyz)
        model.compensate(model.predict(q[:3], load[:3]), q[:3], load[:3])
    # Joint 1 beyond its range on two rows: each call names them and the joint.
    far = q[:5].copy()
    far[1, 0] = joints[0][1] + 15.0
    far[3, 0] = joints[0][0] - 4.0
    for call in (
        lambda: model.predict(far, 0.0),
        lambda: model.evaluate(far, 0.0, model.predict(far, 0.0)),
    ):
        with pytest.warns(Warning, match=r"2 of 5 rows lie outside .* q1 on 2 \(up to"):
            call()
    with pytest.warns(Warning, match=r"commands: \d+ of 5 rows lie outside .* q1 on"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", category=DeprecationWarning)
            model.compensate(model.predict(far, 0.0), far, 0.0)
