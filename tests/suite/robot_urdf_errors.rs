//! Every way a URDF can be unusable gives its own error, never a panic.

use proptest::prelude::*;
use servostack::robot::builtin::AFMA6_URDF;
use servostack::robot::{RobotError, SerialChain};

const LIMIT: &str = r#"<limit lower="-1" upper="1" effort="0" velocity="1"/>"#;

/// A robot with links a, b, c, d and the given joints.
fn urdf(joints: &str) -> String {
    format!(
        r#"<robot name="fixture"><link name="a"/><link name="b"/><link name="c"/><link name="d"/>{joints}</robot>"#
    )
}

/// A joint from `parent` to `child` with a type and extra elements.
fn joint(name: &str, kind: &str, parent: &str, child: &str, extra: &str) -> String {
    format!(
        r#"<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>{extra}</joint>"#
    )
}

/// a → b (revolute) → c (revolute, with `extra` for the second joint).
fn two_joints(second_kind: &str, second_extra: &str) -> String {
    urdf(&format!(
        "{}{}",
        joint("j1", "revolute", "a", "b", LIMIT),
        joint("j2", second_kind, "b", "c", second_extra)
    ))
}

fn load<const N: usize>(xml: &str, base: &str, tip: &str) -> RobotError {
    SerialChain::<N>::from_urdf_str(xml, base, tip).unwrap_err()
}

#[test]
fn the_fixture_itself_loads() {
    let chain = SerialChain::<2>::from_urdf_str(&two_joints("revolute", LIMIT), "a", "c").unwrap();
    assert_eq!(chain.joints()[1].name(), "j2");
}

#[test]
fn malformed_xml() {
    let err = load::<0>(r#"<robot name="x"><link name="a"></robot>"#, "a", "a");
    assert!(matches!(err, RobotError::Urdf { .. }), "{err:?}");
    // Well-formed XML, but a joint without a parent is not URDF.
    let err = load::<0>(
        &urdf(r#"<joint name="j" type="fixed"><child link="b"/></joint>"#),
        "a",
        "a",
    );
    assert!(matches!(err, RobotError::Urdf { .. }), "{err:?}");
    assert!(matches!(load::<0>("", "a", "a"), RobotError::Urdf { .. }));
}

#[test]
fn unknown_base_or_tip() {
    let xml = two_joints("revolute", LIMIT);
    assert_eq!(
        load::<2>(&xml, "z", "c"),
        RobotError::UnknownLink {
            role: "base",
            link: "z".into()
        }
    );
    assert_eq!(
        load::<2>(&xml, "a", "zz"),
        RobotError::UnknownLink {
            role: "tip",
            link: "zz".into()
        }
    );
}

#[test]
fn tip_not_reachable_from_base() {
    let xml = urdf(&format!(
        "{}{}",
        joint("j1", "revolute", "a", "b", LIMIT),
        joint("j2", "revolute", "a", "c", LIMIT)
    ));
    let unreachable = |base: &str, tip: &str| RobotError::TipNotReachable {
        base: base.into(),
        tip: tip.into(),
    };
    // Siblings, and the chain taken backwards.
    assert_eq!(load::<1>(&xml, "b", "c"), unreachable("b", "c"));
    assert_eq!(load::<1>(&xml, "b", "a"), unreachable("b", "a"));
    // A cycle between b and c that never reaches d.
    let cycle = urdf(&format!(
        "{}{}",
        joint("j1", "fixed", "b", "c", ""),
        joint("j2", "fixed", "c", "b", "")
    ));
    assert_eq!(load::<0>(&cycle, "d", "c"), unreachable("d", "c"));
}

#[test]
fn a_link_with_two_parents() {
    let xml = urdf(&format!(
        "{}{}",
        joint("j1", "revolute", "a", "c", LIMIT),
        joint("j2", "revolute", "b", "c", LIMIT)
    ));
    assert_eq!(
        load::<1>(&xml, "a", "c"),
        RobotError::MultipleParents { link: "c".into() }
    );
}

#[test]
fn floating_planar_and_spherical_joints_on_the_path() {
    for kind in ["floating", "planar", "spherical"] {
        let xml = two_joints(kind, "");
        assert_eq!(
            load::<2>(&xml, "a", "c"),
            RobotError::UnsupportedJoint {
                joint: "j2".into(),
                kind
            },
            "{kind}"
        );
    }
    // Off the path they do not matter.
    let xml = urdf(&format!(
        "{}{}",
        joint("j1", "revolute", "a", "b", LIMIT),
        joint("free", "floating", "a", "d", "")
    ));
    assert!(SerialChain::<1>::from_urdf_str(&xml, "a", "b").is_ok());
}

/// A mimic joint on the path is no coordinate of the chain: two joints, one independent.
#[test]
fn mimic_joint_on_the_path_follows_its_leader() {
    let xml = two_joints(
        "revolute",
        &format!(r#"{LIMIT}<mimic joint="j1" multiplier="2" offset="0.1"/>"#),
    );
    assert_eq!(
        load::<2>(&xml, "a", "c"),
        RobotError::JointCount {
            expected: 2,
            found: 1
        }
    );
    let chain = SerialChain::<1>::from_urdf_str(&xml, "a", "c").unwrap();
    let mimic = &chain.mimic_joints()[0];
    assert_eq!(mimic.joint().name(), "j2");
    assert_eq!(
        (mimic.leader(), mimic.multiplier(), mimic.offset()),
        (0, 2.0, 0.1)
    );
}

/// A revolute joint j2 from b to c, mimicking `leader`.
fn j2_mimicking(leader: &str) -> String {
    joint(
        "j2",
        "revolute",
        "b",
        "c",
        &format!(r#"{LIMIT}<mimic joint="{leader}"/>"#),
    )
}

/// a → b (j1) → c (j2, mimic of `leader`), with extra joints.
fn mimic_of(leader: &str, extra_joints: &str) -> String {
    urdf(&format!(
        "{}{}{extra_joints}",
        joint("j1", "revolute", "a", "b", LIMIT),
        j2_mimicking(leader),
    ))
}

#[test]
fn mimic_of_an_unknown_joint() {
    let err = load::<1>(&mimic_of("j9", ""), "a", "c");
    assert_eq!(
        err,
        RobotError::MimicUnknownJoint {
            joint: "j2".into(),
            leader: "j9".into()
        }
    );
    assert_eq!(
        err.to_string(),
        r#"joint "j2" mimics "j9", which is not a joint of the URDF"#
    );
}

#[test]
fn mimic_cycle() {
    // j2 mimics j3 (off the path), which mimics j2.
    let j3 = joint(
        "j3",
        "revolute",
        "c",
        "d",
        &format!(r#"{LIMIT}<mimic joint="j2"/>"#),
    );
    let err = load::<1>(&mimic_of("j3", &j3), "a", "c");
    assert_eq!(
        err,
        RobotError::MimicCycle {
            joints: vec!["j2".into(), "j3".into(), "j2".into()]
        }
    );
    assert_eq!(err.to_string(), "mimic joints form a cycle: j2 → j3 → j2");
    // A joint that mimics itself.
    assert_eq!(
        load::<1>(&mimic_of("j2", ""), "a", "c"),
        RobotError::MimicCycle {
            joints: vec!["j2".into(), "j2".into()]
        }
    );
}

#[test]
fn mimic_of_a_joint_off_the_path_or_fixed() {
    let off_path = joint("j3", "revolute", "a", "d", LIMIT);
    assert_eq!(
        load::<1>(&mimic_of("j3", &off_path), "a", "c"),
        RobotError::MimicLeaderNotOnPath {
            joint: "j2".into(),
            leader: "j3".into()
        }
    );
    // j1 fixed: j2 mimics a joint that is no coordinate.
    let xml = urdf(&format!(
        "{}{}",
        joint("j1", "fixed", "a", "b", ""),
        j2_mimicking("j1"),
    ));
    assert!(matches!(
        load::<0>(&xml, "a", "c"),
        RobotError::MimicLeaderNotOnPath { .. }
    ));
}

#[test]
fn mimic_before_an_independent_joint() {
    let xml = urdf(&format!(
        "{}{}{}",
        joint("j1", "revolute", "a", "b", LIMIT),
        j2_mimicking("j1"),
        joint("j3", "revolute", "c", "d", LIMIT),
    ));
    assert_eq!(
        load::<2>(&xml, "a", "d"),
        RobotError::MimicBeforeJoint {
            joint: "j2".into(),
            next: "j3".into()
        }
    );
}

#[test]
fn non_finite_mimic_multiplier() {
    let xml = two_joints(
        "revolute",
        &format!(r#"{LIMIT}<mimic joint="j1" multiplier="inf"/>"#),
    );
    assert!(matches!(
        load::<1>(&xml, "a", "c"),
        RobotError::NonFiniteUrdf { field: "mimic", .. }
    ));
}

/// A mimic multiplier beyond ±1e6 (composed along a chain of mimics) or an offset beyond ±1000 is out of range: such a
/// joint's angle could overflow the kinematics.
#[test]
fn mimic_multiplier_or_offset_out_of_range() {
    for (attributes, value) in [(r#"multiplier="2e6""#, 2e6), (r#"offset="-5e3""#, -5e3)] {
        let xml = two_joints(
            "revolute",
            &format!(r#"{LIMIT}<mimic joint="j1" {attributes}/>"#),
        );
        match load::<1>(&xml, "a", "c") {
            RobotError::OutOfRange {
                joint,
                field: "mimic",
                value: given,
                ..
            } => assert_eq!((joint.as_str(), given), ("j2", value)),
            other => panic!("{attributes}: expected OutOfRange, got {other:?}"),
        }
    }
}

#[test]
fn joint_count_differs_from_n() {
    let xml = two_joints("revolute", LIMIT);
    assert_eq!(
        load::<3>(&xml, "a", "c"),
        RobotError::JointCount {
            expected: 3,
            found: 2
        }
    );
    assert_eq!(
        load::<1>(&xml, "a", "c"),
        RobotError::JointCount {
            expected: 1,
            found: 2
        }
    );
    // Fixed joints do not count.
    let fixed = two_joints("fixed", "");
    assert!(SerialChain::<1>::from_urdf_str(&fixed, "a", "c").is_ok());
}

#[test]
fn missing_limits() {
    let missing = |lower: f64, upper: f64| RobotError::MissingLimits {
        joint: "j2".into(),
        lower,
        upper,
    };
    // URDF 1.0 without <limit>: urdf-rs reports lower = upper = 0.
    let err = load::<2>(&two_joints("revolute", ""), "a", "c");
    assert_eq!(err, missing(0.0, 0.0));
    // The message says how to supply limits.
    let message = err.to_string();
    assert!(
        message.contains("j2")
            && message.contains("<limit lower=")
            && message.contains("continuous"),
        "{message}"
    );
    assert_eq!(
        load::<2>(&two_joints("prismatic", ""), "a", "c"),
        missing(0.0, 0.0)
    );
    // URDF 1.2 without lower/upper: unlimited, unusable for a revolute or prismatic joint.
    let v12 = two_joints("prismatic", r#"<limit effort="1" velocity="1"/>"#).replace(
        r#"<robot name="fixture">"#,
        r#"<robot name="fixture" version="1.2">"#,
    );
    assert_eq!(
        load::<2>(&v12, "a", "c"),
        missing(f64::NEG_INFINITY, f64::INFINITY)
    );
    // A continuous joint needs none.
    let chain = SerialChain::<2>::from_urdf_str(&two_joints("continuous", ""), "a", "c").unwrap();
    assert_eq!(chain.upper_limits()[1], f64::INFINITY);
}

#[test]
fn inverted_or_empty_limits() {
    for (lower, upper) in [(1.0, -1.0), (0.5, 0.5)] {
        let limit = format!(r#"<limit lower="{lower}" upper="{upper}" effort="0" velocity="1"/>"#);
        let err = load::<2>(&two_joints("prismatic", &limit), "a", "c");
        assert_eq!(
            err,
            RobotError::InvalidLimits {
                joint: "j2".into(),
                lower,
                upper
            }
        );
    }
}

#[test]
fn zero_axis() {
    let xml = two_joints("revolute", &format!(r#"<axis xyz="0 0 0"/>{LIMIT}"#));
    assert_eq!(
        load::<2>(&xml, "a", "c"),
        RobotError::ZeroAxis {
            joint: "j2".into(),
            axis: [0.0; 3]
        }
    );
}

#[test]
fn non_finite_numbers() {
    let cases = [
        (
            r#"<origin xyz="nan 0 0"/>"#.to_owned() + LIMIT,
            "origin xyz",
        ),
        (
            r#"<origin rpy="0 inf 0"/>"#.to_owned() + LIMIT,
            "origin rpy",
        ),
        (r#"<axis xyz="0 -inf 1"/>"#.to_owned() + LIMIT, "axis"),
        (
            r#"<limit lower="NaN" upper="1" effort="0" velocity="1"/>"#.to_owned(),
            "limit",
        ),
    ];
    for (extra, field) in cases {
        match load::<2>(&two_joints("revolute", &extra), "a", "c") {
            RobotError::NonFiniteUrdf {
                joint, field: f, ..
            } => assert_eq!((joint.as_str(), f), ("j2", field)),
            other => panic!("{field}: {other:?}"),
        }
    }
    // A non-finite number in a fixed joint on the path is caught too.
    let xml = two_joints("fixed", r#"<origin xyz="0 0 inf"/>"#);
    assert!(matches!(
        load::<1>(&xml, "a", "c"),
        RobotError::NonFiniteUrdf {
            field: "origin xyz",
            ..
        }
    ));
}

#[test]
fn unreadable_file() {
    let err = SerialChain::<6>::from_urdf_file("/nonexistent/robot.urdf", "a", "b").unwrap_err();
    assert!(
        matches!(err, RobotError::File { ref path, .. } if path == "/nonexistent/robot.urdf"),
        "{err:?}"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Truncated or corrupted URDF gives an error or a chain, never a panic, and never a parser panic either.
    #[test]
    fn corrupted_urdf_never_panics(cut in 0..AFMA6_URDF.len(), at in 0..AFMA6_URDF.len(), byte in 32u8..127) {
        let mut corrupted = AFMA6_URDF.as_bytes().to_vec();
        corrupted[at] = byte;
        // The URDF files are ASCII: any byte index is a char boundary.
        for text in [&AFMA6_URDF[..cut], &String::from_utf8_lossy(&corrupted)] {
            if let Err(RobotError::Urdf { message }) =
                SerialChain::<6>::from_urdf_str(text, "afma6_base", "afma6_end_effector")
            {
                prop_assert!(!message.contains("panicked"), "{}", message);
            }
        }
    }

    #[test]
    fn random_text_never_panics(text in "\\PC{0,200}") {
        let _ = SerialChain::<6>::from_urdf_str(&text, "a", "b");
        let _ = SerialChain::<6>::from_urdf_str(&format!("<robot>{text}</robot>"), "a", "b");
    }
}
