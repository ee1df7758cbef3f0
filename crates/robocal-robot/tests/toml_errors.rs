//! Robot files: every rejection names the file and the line/column or key.

use robocal_robot::{Robot, RobotError};

const GOOD: &str = r#"
name = "two"
[[joint]]
a = 0.0
alpha = 0.0
d = 100.0
theta = 0.0
limits = [-90.0, 90.0]
[[joint]]
a = 300.0
alpha = 90.0
beta = 0.1
d = 0.0
theta = 5.0
[base]
xyz = [1.0, 2.0, 3.0]
rpy = [10.0, 20.0, 30.0]
[tool]
xyz = [0.0, 0.0, 50.0]
"#;

fn parse(text: &str) -> Result<Robot, RobotError> {
    Robot::from_toml_str(text, "arm.toml")
}

#[test]
fn good_file_parses_in_file_units() {
    let r = parse(GOOD).unwrap();
    assert_eq!(r.dof(), 2);
    assert!((r.joints[1].theta.to_degrees() - 5.0).abs() < 1e-12);
    assert!((r.base.rpy.z.to_degrees() - 30.0).abs() < 1e-12);
    assert_eq!(
        r.joints[1]
            .beta
            .map(f64::to_degrees)
            .map(|b| (b * 1e9).round()),
        Some(1e8)
    );
    assert_eq!(r.param_count(), 4 * 2 + 1 + 9);
}

fn toml_error_at(text: &str) -> (usize, usize, String) {
    match parse(text) {
        Err(RobotError::Toml {
            path,
            line,
            column,
            message,
        }) => {
            assert_eq!(path.to_str(), Some("arm.toml"));
            (line, column, message)
        }
        other => panic!("expected a TOML error, got {other:?}"),
    }
}

#[test]
fn unknown_key_is_named_with_its_line() {
    let text = GOOD.replace("theta = 5.0", "theta = 5.0\nlenght = 3.0");
    let (line, _, message) = toml_error_at(&text);
    assert_eq!(line, 15);
    assert!(message.contains("lenght"), "{message}");
}

#[test]
fn missing_key_and_wrong_type_are_reported() {
    let (_, _, message) = toml_error_at(&GOOD.replace("d = 100.0\n", ""));
    assert!(message.contains("missing field `d`"), "{message}");
    let (line, _, message) = toml_error_at(&GOOD.replace("a = 300.0", "a = \"300\""));
    assert_eq!(line, 10);
    assert!(
        message.contains("float") || message.contains("string"),
        "{message}"
    );
    let (_, _, message) =
        toml_error_at(&GOOD.replace("rpy = [10.0, 20.0, 30.0]", "rpy = [10.0, 20.0]"));
    assert!(
        message.contains('3') || message.contains("length"),
        "{message}"
    );
    let (_, _, message) = toml_error_at(&GOOD.replace("[tool]\nxyz = [0.0, 0.0, 50.0]\n", ""));
    assert!(message.contains("tool"), "{message}");
}

#[test]
fn bad_values_name_their_key() {
    let key_of = |text: String| match parse(&text) {
        Err(RobotError::InvalidValue { key, .. }) => key,
        other => panic!("expected an invalid value, got {other:?}"),
    };
    assert_eq!(key_of(GOOD.replace("a = 300.0", "a = nan")), "joint[2].a");
    assert_eq!(key_of(GOOD.replace("d = 100.0", "d = inf")), "joint[1].d");
    assert_eq!(
        key_of(GOOD.replace("[-90.0, 90.0]", "[90.0, -90.0]")),
        "joint[1].limits"
    );
    assert_eq!(
        key_of(GOOD.replace("xyz = [1.0, 2.0, 3.0]", "xyz = [1.0, -inf, 3.0]")),
        "base.xyz"
    );
}

#[test]
fn no_joint_and_missing_file() {
    let no_joints = "name = \"x\"\n[base]\nxyz = [0.0, 0.0, 0.0]\nrpy = [0.0, 0.0, 0.0]\n[tool]\nxyz = [0.0, 0.0, 0.0]\n";
    assert!(matches!(parse(no_joints), Err(RobotError::NoJoints { .. })));
    let err = Robot::load("/nonexistent/robot.toml").unwrap_err();
    assert!(matches!(err, RobotError::Io { .. }));
    assert!(err.to_string().contains("/nonexistent/robot.toml"));
}

#[test]
fn arrays_with_too_many_numbers_are_refused_at_their_line() {
    // base.rpy is on line 17, base.xyz on 16, tool.xyz on 19, the first joint's limits on 8.
    for (from, to, line) in [
        (
            "rpy = [10.0, 20.0, 30.0]",
            "rpy = [10.0, 20.0, 30.0, 40.0]",
            17,
        ),
        ("xyz = [1.0, 2.0, 3.0]", "xyz = [1.0, 2.0]", 16),
        ("xyz = [0.0, 0.0, 50.0]", "xyz = [0.0, 0.0, 50.0, 1.0]", 19),
        ("limits = [-90.0, 90.0]", "limits = [-90.0, 90.0, 0.0]", 8),
    ] {
        let (at, _, message) = toml_error_at(&GOOD.replace(from, to));
        assert_eq!(at, line, "{to}: {message}");
        assert!(message.contains("expected"), "{to}: {message}");
    }
}
