//! Lines in backend pixels: dash patterns continued along a polyline, point markers spaced along it, and the
//! drawing of both (plotters draws dashes of one length only, and no markers along a curve).

use super::*;

/// A point in backend pixels, relative to the drawing area it is drawn on.
pub(super) type Px = (f64, f64);

/// The "on" pieces of the polyline `points` under the pattern `dashes` (on / off lengths in pixels, starting with
/// "on"; empty for a solid line, which is returned whole). The pattern runs on across vertices.
pub(super) fn dash(points: &[Px], dashes: &[f64]) -> Vec<Vec<Px>> {
    let cycle: f64 = dashes.iter().sum();
    if dashes.is_empty() || cycle.is_nan() || cycle <= 0.0 {
        return if points.len() > 1 {
            vec![points.to_vec()]
        } else {
            Vec::new()
        };
    }
    let mut pieces = Vec::new();
    let mut current: Vec<Px> = Vec::new();
    // Index of the current dash or gap, and the length left in it.
    let (mut phase, mut left) = (0, dashes[0]);
    let on = |phase: usize| phase.is_multiple_of(2);
    if let Some(&first) = points.first() {
        current.push(first);
    }
    for pair in points.windows(2) {
        let (mut a, b) = (pair[0], pair[1]);
        let mut length = (b.0 - a.0).hypot(b.1 - a.1);
        while length > left {
            let t = left / length;
            let cut = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
            length -= left;
            a = cut;
            if on(phase) {
                current.push(cut);
                pieces.push(std::mem::take(&mut current));
            } else {
                current.push(cut);
            }
            phase = (phase + 1) % dashes.len();
            left = dashes[phase];
        }
        left -= length;
        if on(phase) {
            current.push(b);
        }
    }
    if on(phase) && current.len() > 1 {
        pieces.push(current);
    }
    pieces
}

/// Points of the polyline `points` every `spacing` pixels of horizontal travel (the sum of `|Δx|`), the first
/// `phase` pixels from its start: evenly spread along the time axis of a curve over time, and never bunched on its
/// steep parts as spacing by arc length would be.
pub(super) fn points_along(points: &[Px], spacing: f64, phase: f64) -> Vec<Px> {
    let mut found = Vec::new();
    if spacing.is_nan() || spacing <= 0.0 {
        return found;
    }
    let mut next = phase.max(0.0);
    let mut travelled = 0.0;
    for pair in points.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let length = (b.0 - a.0).abs();
        while next <= travelled + length && length > 0.0 {
            let t = (next - travelled) / length;
            found.push((a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1)));
            next += spacing;
        }
        travelled += length;
    }
    found
}

fn to_backend((x, y): Px) -> (i32, i32) {
    (x.round() as i32, y.round() as i32)
}

/// Draws the polyline `points` (pixels of `area`) in `color`, `width` layout pixels wide, with `pattern`.
pub(super) fn draw_line<DB: DrawingBackend>(
    area: &Area<DB>,
    points: &[Px],
    color: RGBColor,
    width: u32,
    pattern: LinePattern,
    look: Look,
) -> Drawn<DB> {
    let dashes: Vec<f64> = pattern.dashes().iter().map(|&d| look.pxf(d)).collect();
    for piece in dash(points, &dashes) {
        area.draw(&PathElement::new(
            piece.into_iter().map(to_backend).collect::<Vec<_>>(),
            look.stroke(color, width),
        ))?;
    }
    Ok(())
}

/// Draws `marker` centred at `at` (pixels of `area`): a white-filled symbol outlined in `color`.
pub(super) fn draw_marker<DB: DrawingBackend>(
    area: &Area<DB>,
    at: Px,
    marker: PointMarker,
    color: RGBColor,
    look: Look,
) -> Drawn<DB> {
    let r = look.pxf(MARKER_RADIUS_PX);
    let (x, y) = at;
    let outline: Vec<Px> = match marker {
        PointMarker::Circle => {
            let centre = to_backend(at);
            let radius = r.round() as i32;
            area.draw(&Circle::new(centre, radius, WHITE.filled()))?;
            return area.draw(&Circle::new(centre, radius, look.stroke(color, 2)));
        }
        PointMarker::Plus => {
            let stroke = look.stroke(color, 2);
            let s = 1.2 * r;
            area.draw(&PathElement::new(
                [to_backend((x - s, y)), to_backend((x + s, y))],
                stroke,
            ))?;
            return area.draw(&PathElement::new(
                [to_backend((x, y - s)), to_backend((x, y + s))],
                stroke,
            ));
        }
        PointMarker::Square => {
            let s = 0.9 * r;
            vec![
                (x - s, y - s),
                (x + s, y - s),
                (x + s, y + s),
                (x - s, y + s),
            ]
        }
        PointMarker::Triangle => {
            let s = 1.2 * r;
            vec![(x, y - s), (x + s, y + 0.8 * s), (x - s, y + 0.8 * s)]
        }
        PointMarker::Diamond => {
            let s = 1.3 * r;
            vec![(x, y - s), (x + s, y), (x, y + s), (x - s, y)]
        }
    };
    let corners: Vec<(i32, i32)> = outline.into_iter().map(to_backend).collect();
    area.draw(&Polygon::new(corners.clone(), WHITE.filled()))?;
    let mut closed = corners.clone();
    closed.extend(corners.first().copied());
    area.draw(&PathElement::new(closed, look.stroke(color, 2)))
}

/// Draws a curve of `style` through `points` (pixels of `area`), its markers every [`MARKER_SPACING_PX`] along x
/// from `marker_phase` (a fraction of the spacing, so that the markers of different curves do not coincide).
pub(super) fn draw_curve<DB: DrawingBackend>(
    area: &Area<DB>,
    points: &[Px],
    style: SeriesStyle,
    marker_phase: f64,
    look: Look,
) -> Drawn<DB> {
    draw_line(
        area,
        points,
        style.color,
        SERIES_STROKE_PX,
        style.pattern,
        look,
    )?;
    if let Some(marker) = style.marker {
        let spacing = look.pxf(MARKER_SPACING_PX);
        for at in points_along(points, spacing, marker_phase * spacing) {
            draw_marker(area, at, marker, style.color, look)?;
        }
    }
    Ok(())
}
