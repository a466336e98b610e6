//! Clipping of polylines to the drawn axis ranges.

use super::*;

/// Whether `v` lies in the closed interval `range`.
pub(super) fn within(v: f64, (lo, hi): (f64, f64)) -> bool {
    lo <= v && v <= hi
}

/// The runs of the polyline `points` inside the box `x_range × y_range`, each segment cut at the border.
///
/// Plotters clamps out-of-range coordinates onto the border, which would draw false flat lines there, so data
/// outside an explicit range is clipped here instead. Segments are straight on screen, so they are cut in display
/// coordinates (`log10 y` on a [`Scale::Log10`] axis, whose values validation keeps positive).
pub(super) fn clip_polyline(
    points: &[(f64, f64)],
    x_range: (f64, f64),
    y_range: (f64, f64),
    y_scale: Scale,
) -> Vec<Vec<(f64, f64)>> {
    let y_screen = (y_scale.screen(y_range.0), y_scale.screen(y_range.1));
    let mut runs: Vec<Vec<(f64, f64)>> = Vec::new();
    if let [only] = points {
        if within(only.0, x_range) && within(only.1, y_range) {
            runs.push(vec![*only]);
        }
        return runs;
    }
    // Whether the last run ends at the start of the current segment.
    let mut open = false;
    for pair in points.windows(2) {
        let &[a, b] = pair else { continue };
        let ((xa, ya), (xb, yb)) = ((a.0, y_scale.screen(a.1)), (b.0, y_scale.screen(b.1)));
        // A segment touching the box in one point draws nothing.
        let Some((t0, t1)) =
            clip_segment((xa, ya), (xb, yb), x_range, y_screen).filter(|(t0, t1)| t0 < t1)
        else {
            open = false;
            continue;
        };
        // Kept endpoints are copied exactly; cut points are interpolated on screen.
        let at = |t: f64| match t {
            0.0 => a,
            1.0 => b,
            _ => (xa + t * (xb - xa), y_scale.unscreen(ya + t * (yb - ya))),
        };
        match runs.last_mut() {
            Some(run) if open && t0 == 0.0 => run.push(at(t1)),
            _ => runs.push(vec![at(t0), at(t1)]),
        }
        open = t1 == 1.0;
    }
    runs
}

/// Liang–Barsky: the parameter interval `[t0, t1] ⊂ [0, 1]` of the segment `a + t (b - a)` inside the box, if any.
pub(super) fn clip_segment(
    a: (f64, f64),
    b: (f64, f64),
    x_range: (f64, f64),
    y_range: (f64, f64),
) -> Option<(f64, f64)> {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
    // Each constraint p t <= q keeps the point on the inner side of one border.
    for (p, q) in [
        (-dx, a.0 - x_range.0),
        (dx, x_range.1 - a.0),
        (-dy, a.1 - y_range.0),
        (dy, y_range.1 - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else if p < 0.0 {
            t0 = t0.max(q / p);
        } else {
            t1 = t1.min(q / p);
        }
    }
    (t0 <= t1).then_some((t0, t1))
}
