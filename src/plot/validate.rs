//! Validation of figure data before any file is touched: points, axis ranges, file stems (sizes:
//! [`FigureStyle`]).

use super::*;

/// Data extent `(min, max)` on each axis, `None` until a value is included.
#[derive(Debug, Default)]
pub(super) struct Bounds {
    pub(super) x: Option<(f64, f64)>,
    pub(super) y: Option<(f64, f64)>,
}

impl Bounds {
    pub(super) fn include(&mut self, (x, y): (f64, f64)) {
        self.include_x(x);
        self.include_y(y);
    }
    pub(super) fn include_x(&mut self, x: f64) {
        self.x = Some(extend(self.x, x));
    }
    pub(super) fn include_y(&mut self, y: f64) {
        self.y = Some(extend(self.y, y));
    }
}

fn extend(range: Option<(f64, f64)>, v: f64) -> (f64, f64) {
    range.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v)))
}

/// Rejects an empty point list, non-finite coordinates and, on a log axis, non-positive ordinates.
pub(super) fn check_points(
    item: &str,
    points: &[(f64, f64)],
    log_y: bool,
) -> Result<(), PlotError> {
    if points.is_empty() {
        return Err(PlotError::EmptySeries {
            series: item.to_owned(),
        });
    }
    for (index, &(x, y)) in points.iter().enumerate() {
        if !(x.is_finite() && y.is_finite()) {
            return Err(PlotError::NonFinite {
                item: item.to_owned(),
                index,
                x,
                y,
            });
        }
        if log_y && y <= 0.0 {
            return Err(PlotError::NonPositiveOnLogAxis {
                item: item.to_owned(),
                index,
                y,
            });
        }
    }
    Ok(())
}

/// The drawn range of one axis: the explicit one if given (validated), else the data extent with a margin.
pub(super) fn axis_range(
    axis: &'static str,
    explicit: Option<(f64, f64)>,
    data: Option<(f64, f64)>,
    scale: Scale,
) -> Result<(f64, f64), PlotError> {
    if let Some((min, max)) = explicit {
        let positive = scale == Scale::Linear || min > 0.0;
        if !(min.is_finite() && max.is_finite() && min < max && positive) {
            return Err(PlotError::InvalidRange { axis, min, max });
        }
        return Ok((min, max));
    }
    // Validation guarantees at least one finite point on each axis; (0, 1) only guards the unreachable case.
    let (lo, hi) = data.unwrap_or((0.0, 1.0));
    Ok(match scale {
        Scale::Linear => {
            let span = hi - lo;
            let pad = if span > f64::EPSILON * lo.abs().max(hi.abs()) {
                0.05 * span
            } else if lo == 0.0 {
                0.5
            } else {
                0.1 * lo.abs()
            };
            (lo - pad, hi + pad)
        }
        Scale::Log10 => {
            // Half a decade around a constant, else 5 % of the span in decades.
            let decades = (hi / lo).log10();
            let pad = if decades > 1e-9 { 0.05 * decades } else { 0.5 };
            (lo / 10f64.powf(pad), hi * 10f64.powf(pad))
        }
    })
}

pub(super) fn check_stem(stem: &str) -> Result<(), PlotError> {
    let plain = !stem.is_empty()
        && stem != "."
        && stem != ".."
        && Path::new(stem).file_name().and_then(|n| n.to_str()) == Some(stem);
    if plain {
        Ok(())
    } else {
        Err(PlotError::InvalidStem {
            stem: stem.to_owned(),
        })
    }
}
