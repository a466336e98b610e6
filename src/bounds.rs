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

/// Finite joint acceleration limits (rad/s², m/s²) of a simulation (`+∞`, no limit, is checked apart). A nanometre per
/// second squared takes eleven days to reach a millimetre per second; a million per second squared is a hundred
/// thousand g, far beyond any robot, and far below where `a²Δt²` in the stopping distance of
/// [`braking_speed`](crate::avoidance::braking_speed) leaves the range of `f64`.
pub const ACCELERATION_PER_S2: PhysicalRange = PhysicalRange {
    low: 1e-9,
    high: 1e6,
    text: "within [1e-9, 1e6] (rad/s², m/s²), or +∞ for no limit",
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

/// Depths and target sizes (m): a micrometre to a kilometre. Below, a target images to a fraction of a pixel and an
/// interaction matrix's `1/Z` terms reach a million per metre; above, nothing of [`LENGTH_M`] is that far.
pub const DEPTH_M: PhysicalRange = PhysicalRange {
    low: 1e-6,
    high: 1e3,
    text: "finite, within [1e-6, 1000] m",
};

/// Focal lengths (px). A pixel-sized focal length is already a fisheye of about 180°; a million pixels is a
/// telescope on a gigapixel sensor. A value outside is a unit error (metres or millimetres for pixels).
pub const FOCAL_LENGTH_PX: PhysicalRange = PhysicalRange {
    low: 1.0,
    high: 1e6,
    text: "finite, within [1, 1e6] px",
};

/// Image sizes (px), width or height: one pixel to a million.
pub const IMAGE_SIZE_PX: PhysicalRange = PhysicalRange {
    low: 1.0,
    high: 1e6,
    text: "finite, within [1, 1e6] px",
};

/// Principal-point coordinates (px): within a million pixels of the image's corner either way (a principal point far
/// outside the image is a shifted-lens or cropped camera, but never beyond the sensor sizes of [`IMAGE_SIZE_PX`]).
pub const PRINCIPAL_POINT_PX: PhysicalRange = PhysicalRange {
    low: -1e6,
    high: 1e6,
    text: "finite, within ±1e6 px",
};

/// Pixel noise amplitudes (px): the half-width of a uniform noise or the standard deviation of a Gaussian one. A
/// thousand pixels is the size of a whole image: past that nothing is measured, and the noise's arithmetic would be
/// an overflow away (a uniform draw over `±1e308` has an infinite width).
pub const PIXEL_NOISE_PX: PhysicalRange = PhysicalRange {
    low: 0.0,
    high: 1e3,
    text: "finite, within [0, 1000] px",
};

/// Brown–Conrady distortion coefficients (dimensionless): real calibrations stay within a few units (strong fisheye
/// fits reach tens); ten thousand keeps the distortion of any point of an image within [`IMAGE_SIZE_PX`] finite.
pub const DISTORTION_COEFFICIENT: PhysicalRange = PhysicalRange {
    low: -1e4,
    high: 1e4,
    text: "finite, within ±1e4",
};

/// Rates (Hz): camera frame rates, control rates. From one frame an hour to a megahertz.
pub const RATE_HZ: PhysicalRange = PhysicalRange {
    low: 1.0 / 3600.0,
    high: 1e6,
    text: "finite, within [1/3600, 1e6] Hz",
};

/// The largest iteration budget of a simulated run: ten million control periods are 2.8 hours of a 1 kHz loop, and
/// about a minute of computation; a larger count is a typing error that would start a job of hours or years.
pub const MAX_ITERATIONS: usize = 10_000_000;

/// Why [`read_capped`] read nothing.
pub(crate) enum ReadFailure {
    /// The operating system's error.
    Io(std::io::Error),
    /// The file has more than the limit's bytes (the size found: the file's length, or `limit + 1` when its length
    /// is unknown in advance, as for a pipe or a device).
    TooLarge(u64),
}

/// Reads a file of at most `limit` bytes through a reader that stops after `limit + 1` bytes, so that neither a
/// large file nor one whose length is unknown (a pipe, `/dev/zero`) is read whole ([D17](crate::theory#d17)).
pub(crate) fn read_capped(path: &std::path::Path, limit: usize) -> Result<Vec<u8>, ReadFailure> {
    use std::io::Read;
    let file = std::fs::File::open(path).map_err(ReadFailure::Io)?;
    let announced = file.metadata().map_err(ReadFailure::Io)?.len();
    if announced > limit as u64 {
        return Err(ReadFailure::TooLarge(announced));
    }
    let mut bytes = Vec::with_capacity(announced as usize);
    file.take(limit as u64 + 1)
        .read_to_end(&mut bytes)
        .map_err(ReadFailure::Io)?;
    if bytes.len() > limit {
        return Err(ReadFailure::TooLarge(bytes.len() as u64));
    }
    Ok(bytes)
}

/// Reads a UTF-8 text file of at most `limit` bytes ([`read_capped`]): the parsers' inputs.
pub(crate) fn read_text_file(path: &std::path::Path, limit: usize) -> Result<String, ReadFailure> {
    String::from_utf8(read_capped(path, limit)?)
        .map_err(|e| ReadFailure::Io(std::io::Error::new(std::io::ErrorKind::InvalidData, e)))
}
