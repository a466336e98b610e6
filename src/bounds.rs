//! The physical ranges every input is checked against before it reaches a parser or a loop ([D17](crate::theory#d17)).
//!
//! A value outside these ranges is a unit or typing error (millimetres written as metres, degrees as radians, a
//! missing decimal point), never a robot or a scene this crate serves; rejecting it by name keeps every later
//! computation finite: with lengths and joint positions within `±1e3`, gains within `1e6` s⁻¹ and times within a day,
//! the sums, products and squares the kinematics, costs and predictions form stay far below `f64::MAX ≈ 1.8e308`. The
//! validators of the crate (URDF loading, joint limits, gains, controller and simulation parameters, scenario poses
//! and targets) share these constants, so a range is changed in one place.
//!
//! ```
//! use servostack::bounds::{LENGTH_M, PERIOD_S};
//! assert!(LENGTH_M.contains(-2.5));
//! assert!(!LENGTH_M.contains(1e308));
//! assert!(!PERIOD_S.contains(0.0));
//! assert!(!PERIOD_S.contains(f64::NAN));
//! ```

/// A closed range `[low, high]` of admissible values of one physical quantity, with its text for error messages.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhysicalRange {
    /// The smallest admissible value.
    pub low: f64,
    /// The largest admissible value.
    pub high: f64,
    /// The range as error messages state it (`"finite, within ±1000 m"`).
    pub text: &'static str,
}

impl PhysicalRange {
    /// `true` when `value` is finite and within `[low, high]` (NaN and infinities are never admissible).
    pub fn contains(&self, value: f64) -> bool {
        value.is_finite() && self.low <= value && value <= self.high
    }

    /// `true` when every value is [contained](Self::contains).
    pub fn contains_all(&self, values: &[f64]) -> bool {
        values.iter().all(|&v| self.contains(v))
    }
}

/// Lengths and positions (m): URDF origins and prismatic limits, poses of scenario files, target sizes. A kilometre is
/// ten times the reach of the largest gantry robots.
pub const LENGTH_M: PhysicalRange = PhysicalRange {
    low: -1e3,
    high: 1e3,
    text: "finite, within ±1000 m",
};

/// Angles (rad): URDF roll–pitch–yaw and revolute limits. ±1000 rad is about 160 turns, more than any multi-turn
/// joint; a value in degrees by mistake (≤ 360) still passes, one in millidegrees does not.
pub const ANGLE_RAD: PhysicalRange = PhysicalRange {
    low: -1e3,
    high: 1e3,
    text: "finite, within ±1000 rad",
};

/// Joint positions and limits of either kind (m for prismatic joints, rad for revolute ones): [`LENGTH_M`] and
/// [`ANGLE_RAD`] have the same bounds, so a cost over mixed joints needs one range.
pub const JOINT_POSITION: PhysicalRange = PhysicalRange {
    low: -1e3,
    high: 1e3,
    text: "finite, within ±1000 (m or rad)",
};

/// Joint coordinates the kinematics accept (m or rad), far beyond any joint's limits (positions outside the limits are
/// the caller's business) yet small enough that nothing overflows: with origins within [`LENGTH_M`], unit axes and
/// mimic multipliers within [`MIMIC_MULTIPLIER`], every translation of the chain is a sum of a few dozen terms below
/// 1e106 and every Jacobian entry a cross product of a unit axis with a difference of two such translations, so the
/// pose and the Jacobians are finite by construction and the kinematics need not check them.
pub const KINEMATIC_COORDINATE: PhysicalRange = PhysicalRange {
    low: -1e100,
    high: 1e100,
    text: "finite, within ±1e100 (m or rad)",
};

/// Multipliers of URDF mimic joints, composed along a chain of mimics (`θ = m q + o`): a gear ratio beyond a million is
/// a typing error.
pub const MIMIC_MULTIPLIER: PhysicalRange = PhysicalRange {
    low: -1e6,
    high: 1e6,
    text: "finite, within ±1e6",
};

/// Gains (s⁻¹): task gains `λ_i`, the transition gain `μ`, the avoidance gain `κ`. A million per second is a time
/// constant of a microsecond, a thousand times faster than a 1 kHz loop can realise.
pub const GAIN_PER_S: PhysicalRange = PhysicalRange {
    low: 0.0,
    high: 1e6,
    text: "finite, within [0, 1e6] s⁻¹",
};

/// The transition gain `μ` (s⁻¹) of the control law: [`GAIN_PER_S`] without its slowest part. `1/μ` is the length of
/// a transition and sets the controller's prediction horizon (`n_look/μ`), so it must stay below a day: 1e−3 s⁻¹ is a
/// transition of a quarter of an hour.
pub const TRANSITION_GAIN_PER_S: PhysicalRange = PhysicalRange {
    low: 1e-3,
    high: 1e6,
    text: "finite, within [1e-3, 1e6] s⁻¹",
};

/// Durations (s): horizons, dwell times, timeouts. A day.
pub const DURATION_S: PhysicalRange = PhysicalRange {
    low: 0.0,
    high: 86_400.0,
    text: "finite, within [0, 86400] s",
};

/// Control periods (s): from a microsecond (1 MHz) to a minute.
pub const PERIOD_S: PhysicalRange = PhysicalRange {
    low: 1e-6,
    high: 60.0,
    text: "finite, within [1e-6, 60] s",
};

/// Why [`read_text_file`] read nothing.
pub(crate) enum ReadFailure {
    /// The operating system's error.
    Io(std::io::Error),
    /// The file's size (bytes), above the limit.
    TooLarge(u64),
}

/// Reads a text file of at most `limit` bytes, refusing a larger one before reading it (the parsers' inputs,
/// [D17](crate::theory#d17)).
pub(crate) fn read_text_file(path: &std::path::Path, limit: usize) -> Result<String, ReadFailure> {
    let bytes = std::fs::metadata(path).map_err(ReadFailure::Io)?.len();
    if bytes > limit as u64 {
        return Err(ReadFailure::TooLarge(bytes));
    }
    std::fs::read_to_string(path).map_err(ReadFailure::Io)
}
