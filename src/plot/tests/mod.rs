//! Figures are written under `std::env::temp_dir()` and removed afterwards; set `SERVOSTACK_KEEP_FIGURES=1` to
//! keep them for inspection. The SVG readers here are shared with the report's tests.

use super::line::place_labels;
use super::trajectory::equalise_aspect;
use super::*;
use approx::assert_relative_eq;

/// A fresh, unique output directory for one test.
pub(crate) struct OutDir(pub(crate) PathBuf);

impl OutDir {
    pub(crate) fn new(test: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("servostack-plot-{}-{test}", std::process::id()));
        std::fs::remove_dir_all(&dir).ok();
        Self(dir)
    }
}

impl Drop for OutDir {
    fn drop(&mut self) {
        if std::env::var_os("SERVOSTACK_KEEP_FIGURES").is_none() {
            std::fs::remove_dir_all(&self.0).ok();
        }
    }
}

/// Width and height from the IHDR chunk of a PNG file, after checking the signature.
fn png_dimensions(bytes: &[u8]) -> (u32, u32) {
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    assert_eq!(&bytes[12..16], b"IHDR", "first chunk is IHDR");
    let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
    (be(&bytes[16..20]), be(&bytes[20..24]))
}

/// Checks both files: PNG of the right size and not blank, SVG containing every expected text.
fn assert_rendered(files: &RenderedFiles, size: (u32, u32), texts: &[&str]) {
    let png = std::fs::read(&files.png).unwrap();
    assert_eq!(png_dimensions(&png), size);
    // A blank white 1024x640 PNG compresses to a few kB; drawn curves and text give far more.
    assert!(png.len() > 10_000, "PNG only {} bytes", png.len());
    let svg = std::fs::read_to_string(&files.svg).unwrap();
    assert!(svg.starts_with("<svg"), "SVG header");
    assert!(svg.contains(&format!(r#"width="{}" height="{}""#, size.0, size.1)));
    assert!(
        svg.contains(FONT_FAMILY),
        "text uses the embedded font family"
    );
    for text in texts {
        assert!(
            svg.lines().any(|line| line.trim() == *text),
            "SVG lacks text {text:?}"
        );
    }
}

fn joints_plot() -> LinePlot {
    let n = 400;
    let series = (0..6)
        .map(|j| {
            let phase = f64::from(j) * 0.9;
            Series::new(
                format!("q{}", j + 1),
                (0..n).map(|k| {
                    let t = f64::from(k) / f64::from(n);
                    (
                        f64::from(k),
                        0.5 + 0.45 * (6.0 * t + phase).sin() * (1.0 - 0.5 * t),
                    )
                }),
            )
        })
        .collect();
    LinePlot {
        title: "Normalised joint positions".into(),
        x_label: "iteration".into(),
        y_label: "normalised joint position".into(),
        series,
        markers: vec![
            Marker::new(60.0, "push e2"),
            Marker::new(70.0, "push e3"),
            Marker::new(78.0, "remove e1"),
            Marker::new(250.0, "reinsert e1"),
        ],
        horizontal_lines: vec![
            HorizontalLine::new(0.0, "joint limits"),
            HorizontalLine::new(1.0, "joint limits"),
        ],
        y_range: Some((-0.1, 1.1)),
        ..LinePlot::default()
    }
}

#[test]
fn tick_labels_are_short_and_exact() {
    assert_eq!(format_tick(50.0, 400.0), "50");
    assert_eq!(format_tick(0.1 + 0.2, 1.0), "0.3");
    assert_eq!(format_tick(-0.25, 1.0), "-0.25");
    assert_eq!(format_tick(-1.3e-17, 0.6), "0");
    assert_eq!(format_tick(-0.0, 0.6), "0");
    assert_eq!(format_tick(10f64.powf(-4.000_000_000_1), 0.0), "1e-4");
    assert_eq!(format_tick(0.001, 0.0), "0.001");
    assert_eq!(format_tick(2.5e7, 1e8), "2.5e7");
    assert_eq!(format_tick(123_456.0, 1e6), "123456");
}

#[test]
fn line_plot_writes_png_and_svg_with_text() {
    let out = OutDir::new("lines");
    let plot = joints_plot();
    let files = plot.render(&out.0, "joints").unwrap();
    assert_eq!(files.png, out.0.join("joints.png"));
    assert_eq!(files.svg, out.0.join("joints.svg"));
    assert_rendered(
        &files,
        DEFAULT_SIZE,
        &[
            "Normalised joint positions",
            "iteration",
            "normalised joint position",
            "q1",
            "q6",
            "joint limits",
            "push e2",
            "reinsert e1",
        ],
    );
    // The two reference lines share one legend entry.
    let svg = std::fs::read_to_string(&files.svg).unwrap();
    assert_eq!(
        svg.lines()
            .filter(|line| line.trim() == "joint limits")
            .count(),
        1
    );
}

#[test]
fn log_scale_plot_renders_decades() {
    let out = OutDir::new("log");
    let plot = LinePlot {
        title: "Task errors".into(),
        x_label: "iteration".into(),
        y_label: "‖e‖".into(),
        series: (1..=3)
            .map(|i| {
                let rate = 0.02 * f64::from(i);
                Series::new(
                    format!("‖e{i}‖"),
                    (0..300).map(move |k| (f64::from(k), 0.5 * (-rate * f64::from(k)).exp())),
                )
            })
            .collect(),
        y_scale: Scale::Log10,
        style: FigureStyle::new(800, 500),
        ..LinePlot::default()
    };
    let files = plot.render(&out.0, "errors").unwrap();
    assert_rendered(&files, (800, 500), &["Task errors", "‖e1‖", "‖e3‖"]);
}

fn image_plot() -> TrajectoryPlot {
    let start = [(-0.25, -0.15), (0.2, -0.2), (0.22, 0.18), (-0.2, 0.2)];
    let desired = [(-0.1, -0.1), (0.1, -0.1), (0.1, 0.1), (-0.1, 0.1)];
    let trajectories = start
        .iter()
        .zip(&desired)
        .enumerate()
        .map(|(i, (&(x0, y0), &(xd, yd)))| {
            let points = (0..=100).map(move |k| {
                let s = f64::from(k) / 100.0;
                let bend = 0.05 * (std::f64::consts::PI * s).sin();
                (x0 + (xd - x0) * s + bend, y0 + (yd - y0) * s)
            });
            Trajectory::new(format!("point {}", i + 1), points, Some((xd, yd)))
        })
        .collect();
    TrajectoryPlot {
        title: "Image trajectories".into(),
        x_label: "x = X/Z".into(),
        y_label: "y = Y/Z".into(),
        trajectories,
        ..TrajectoryPlot::default()
    }
}

#[test]
fn trajectory_plot_writes_png_and_svg_with_text() {
    let out = OutDir::new("image");
    let files = image_plot().render(&out.0, "image").unwrap();
    assert_rendered(
        &files,
        DEFAULT_SIZE,
        &[
            "Image trajectories",
            "x = X/Z",
            "y = Y/Z",
            "point 1",
            "point 4",
            "start",
            "desired",
        ],
    );
}

/// `(x, y, content)` of every `<text>` element of an SVG written by plotters.
pub(crate) fn svg_texts(svg: &str) -> Vec<(f64, f64, String)> {
    let attr = |tag: &str, name: &str| -> f64 {
        let start = tag.find(&format!(" {name}=\"")).unwrap() + name.len() + 3;
        let len = tag[start..].find('"').unwrap();
        tag[start..start + len].parse().unwrap()
    };
    svg.split("<text ")
        .skip(1)
        .map(|chunk| {
            let (tag, rest) = chunk.split_once('>').unwrap();
            let tag = format!(" {tag}");
            let content = rest.split("</text>").next().unwrap().trim().to_owned();
            (attr(&tag, "x"), attr(&tag, "y"), content)
        })
        .collect()
}

fn text_position(texts: &[(f64, f64, String)], content: &str) -> (f64, f64) {
    let found = texts.iter().find(|t| t.2 == content);
    let (x, y, _) = found.unwrap_or_else(|| panic!("no text {content:?}"));
    (*x, *y)
}

#[test]
fn legend_is_right_of_the_data_and_event_labels_are_staggered() {
    let out = OutDir::new("layout");
    let files = joints_plot().render(&out.0, "joints").unwrap();
    let svg = std::fs::read_to_string(&files.svg).unwrap();
    // Rightmost pixel of any curve or line.
    let data_right = svg
        .split("points=\"")
        .skip(1)
        .flat_map(|chunk| chunk.split('"').next().unwrap().split_whitespace())
        .map(|point| point.split(',').next().unwrap().parse::<f64>().unwrap())
        .fold(f64::NEG_INFINITY, f64::max);
    let texts = svg_texts(&svg);
    for name in ["q1", "q6", "joint limits"] {
        assert!(
            text_position(&texts, name).0 > data_right,
            "legend entry {name:?} overlaps the data"
        );
    }
    // Events at 60, 70 and 78 are a few pixels apart: three rows. The event at 250 is far: first row.
    let rows: Vec<f64> = ["push e2", "push e3", "remove e1", "reinsert e1"]
        .iter()
        .map(|label| text_position(&texts, label).1)
        .collect();
    assert!(
        rows[0] > rows[1] && rows[1] > rows[2],
        "close labels not stacked: {rows:?}"
    );
    assert_eq!(rows[3], rows[0]);
}

/// Pixel row of the start circle of a single trajectory going from y = -1 to y = +1.
fn start_circle_row(y_down: bool) -> f64 {
    let out = OutDir::new(if y_down { "down" } else { "up" });
    let plot = TrajectoryPlot {
        trajectories: vec![Trajectory::new("p", [(0.0, -1.0), (0.0, 1.0)], None)],
        y_down,
        ..TrajectoryPlot::default()
    };
    let files = plot.render(&out.0, "flip").unwrap();
    let svg = std::fs::read_to_string(&files.svg).unwrap();
    let circle = svg.split("<circle ").nth(1).unwrap();
    let cy = circle
        .split("cy=\"")
        .nth(1)
        .unwrap()
        .split('"')
        .next()
        .unwrap();
    cy.parse().unwrap()
}

#[test]
fn image_y_axis_points_down() {
    let (_, height) = DEFAULT_SIZE;
    let half = f64::from(height) / 2.0;
    assert!(
        start_circle_row(true) < half,
        "y = -1 must be at the top of a camera image"
    );
    assert!(
        start_circle_row(false) > half,
        "y = -1 must be at the bottom of an upward axis"
    );
}

#[test]
fn equal_aspect_matches_units_per_pixel() {
    // x spans 2 on 400 px (0.005/px), y spans 1 on 100 px (0.01/px): x widens to 4 about its centre 1.
    let (x, y) = equalise_aspect((0.0, 2.0), (0.0, 1.0), 400, 100);
    assert_eq!((x, y), ((-1.0, 3.0), (0.0, 1.0)));
    // x spans 4 on 400 px (0.01/px), y spans 1 on 200 px (0.005/px): y widens to 2 about its centre 0.5.
    let (x, y) = equalise_aspect((0.0, 4.0), (0.0, 1.0), 400, 200);
    assert_eq!((x, y), ((0.0, 4.0), (-0.5, 1.5)));
}

#[test]
fn segments_are_cut_at_the_border() {
    let unit = (0.0, 1.0);
    assert_eq!(
        clip_segment((-1.0, 0.5), (2.0, 0.5), unit, unit),
        Some((1.0 / 3.0, 2.0 / 3.0))
    );
    assert_eq!(
        clip_segment((0.25, 0.5), (0.75, 0.5), unit, unit),
        Some((0.0, 1.0))
    );
    assert_eq!(clip_segment((-1.0, 2.0), (2.0, 2.0), unit, unit), None);
    // Diagonal through the corner region outside: misses the box.
    assert_eq!(clip_segment((-1.0, 0.5), (0.5, 2.0), unit, unit), None);
}

#[test]
fn polylines_split_into_runs_inside_the_box() {
    let unit = (0.0, 1.0);
    // Up through the top border (y = 1 at x = 0.3), back down through it (at x = 0.7).
    let zigzag = [(0.1, 0.5), (0.5, 1.5), (0.9, 0.5)];
    let runs = clip_polyline(&zigzag, unit, unit, Scale::Linear);
    let expected = [[(0.1, 0.5), (0.3, 1.0)], [(0.7, 1.0), (0.9, 0.5)]];
    assert_eq!(runs.len(), expected.len(), "{runs:?}");
    for (run, want) in runs.iter().zip(&expected) {
        assert_eq!(run.len(), want.len(), "{runs:?}");
        for (got, want) in run.iter().zip(want) {
            assert_relative_eq!(got.0, want.0, epsilon = 1e-12);
            assert_relative_eq!(got.1, want.1, epsilon = 1e-12);
        }
    }
    // A vertex touching the border from outside adds no zero-length piece.
    let touch = [(0.5, 1.5), (0.7, 1.0), (0.9, 0.5)];
    assert_eq!(
        clip_polyline(&touch, unit, unit, Scale::Linear),
        vec![vec![(0.7, 1.0), (0.9, 0.5)]]
    );
    // Fully inside: one run, unchanged.
    let inside = [(0.1, 0.1), (0.2, 0.9), (0.3, 0.1)];
    assert_eq!(
        clip_polyline(&inside, unit, unit, Scale::Linear),
        vec![inside.to_vec()]
    );
    // A single point is kept only inside.
    assert_eq!(
        clip_polyline(&[(0.5, 0.5)], unit, unit, Scale::Linear).len(),
        1
    );
    assert!(clip_polyline(&[(1.5, 0.5)], unit, unit, Scale::Linear).is_empty());
}

#[test]
fn log_axis_cuts_in_decades() {
    // log10 y goes linearly from -3 to 1 over x in [0, 1]: it crosses -2 at x = 0.25 and 0 at x = 0.75.
    let runs = clip_polyline(
        &[(0.0, 1e-3), (1.0, 10.0)],
        (0.0, 1.0),
        (1e-2, 1.0),
        Scale::Log10,
    );
    assert_eq!(runs.len(), 1);
    let [(x0, y0), (x1, y1)] = runs[0][..] else {
        panic!("{runs:?}")
    };
    assert_relative_eq!(x0, 0.25, epsilon = 1e-12);
    assert_relative_eq!(y0, 1e-2, max_relative = 1e-12);
    assert_relative_eq!(x1, 0.75, epsilon = 1e-12);
    assert_relative_eq!(y1, 1.0, max_relative = 1e-12);
}

#[test]
fn automatic_ranges_pad_the_data() {
    let r = axis_range("y", None, Some((0.0, 10.0)), Scale::Linear).unwrap();
    assert_eq!(r, (-0.5, 10.5));
    // Constant data: ±10 % of the value, or ±0.5 around zero.
    assert_eq!(
        axis_range("y", None, Some((2.0, 2.0)), Scale::Linear).unwrap(),
        (1.8, 2.2)
    );
    assert_eq!(
        axis_range("y", None, Some((0.0, 0.0)), Scale::Linear).unwrap(),
        (-0.5, 0.5)
    );
    // Three decades: 0.15 decade each side.
    let (lo, hi) = axis_range("y", None, Some((1e-3, 1.0)), Scale::Log10).unwrap();
    assert_relative_eq!(lo.log10(), -3.15, epsilon = 1e-12);
    assert_relative_eq!(hi.log10(), 0.15, epsilon = 1e-12);
    // An explicit range wins.
    assert_eq!(
        axis_range("x", Some((1.0, 2.0)), Some((0.0, 9.0)), Scale::Linear).unwrap(),
        (1.0, 2.0)
    );
}

/// Renders `plot`, expects `expected` and checks that nothing was written.
fn assert_line_error(plot: &LinePlot, stem: &str, expected: &PlotError) {
    let out = OutDir::new("bad");
    assert_eq!(&plot.render(&out.0, stem).unwrap_err(), expected);
    assert!(!out.0.exists(), "no output on invalid input");
}

#[test]
fn invalid_line_plots_are_errors() {
    let good = || LinePlot {
        title: "t".into(),
        series: vec![Series::new("a", [(0.0, 1.0), (1.0, 2.0)])],
        ..LinePlot::default()
    };
    let no_series = LinePlot {
        series: vec![],
        ..good()
    };
    assert_line_error(&no_series, "f", &PlotError::NoSeries { figure: "t".into() });

    let mut empty = good();
    empty.series.push(Series::new("b", []));
    assert_line_error(&empty, "f", &PlotError::EmptySeries { series: "b".into() });

    let mut nan = good();
    nan.series[0].points[1].1 = f64::NAN;
    let err = nan.render(&OutDir::new("nan").0, "f").unwrap_err();
    assert!(
        matches!(&err, PlotError::NonFinite { item, index: 1, x, y } if item == "a" && *x == 1.0 && y.is_nan()),
        "{err:?}"
    );

    let mut marker = good();
    marker.markers.push(Marker::new(f64::INFINITY, "push"));
    let expected = PlotError::NonFinite {
        item: "push".into(),
        index: 0,
        x: f64::INFINITY,
        y: 0.0,
    };
    assert_line_error(&marker, "f", &expected);

    let mut log = good();
    log.y_scale = Scale::Log10;
    log.series[0].points[0].1 = 0.0;
    let expected = PlotError::NonPositiveOnLogAxis {
        item: "a".into(),
        index: 0,
        y: 0.0,
    };
    assert_line_error(&log, "f", &expected);

    let mut log_range = good();
    log_range.y_scale = Scale::Log10;
    log_range.y_range = Some((0.0, 1.0));
    let expected = PlotError::InvalidRange {
        axis: "y",
        min: 0.0,
        max: 1.0,
    };
    assert_line_error(&log_range, "f", &expected);

    let mut reversed = good();
    reversed.x_range = Some((2.0, 1.0));
    let expected = PlotError::InvalidRange {
        axis: "x",
        min: 2.0,
        max: 1.0,
    };
    assert_line_error(&reversed, "f", &expected);

    let small = LinePlot {
        style: FigureStyle::new(100, 100),
        ..good()
    };
    let expected = PlotError::InvalidSize {
        width: 100,
        height: 100,
    };
    assert_line_error(&small, "f", &expected);

    for stem in ["", ".", "..", "../f", "a/b"] {
        let expected = PlotError::InvalidStem { stem: stem.into() };
        assert_line_error(&good(), stem, &expected);
    }
}

#[test]
fn invalid_trajectory_plots_are_errors() {
    let out = OutDir::new("bad-trajectory");
    let empty = TrajectoryPlot::default();
    assert_eq!(
        empty.render(&out.0, "f").unwrap_err(),
        PlotError::NoSeries {
            figure: String::new()
        }
    );
    let desired_nan = TrajectoryPlot {
        trajectories: vec![Trajectory::new("p", [(0.0, 0.0)], Some((0.0, f64::NAN)))],
        ..TrajectoryPlot::default()
    };
    let err = desired_nan.render(&out.0, "f").unwrap_err();
    assert!(
        matches!(&err, PlotError::NonFinite { item, .. } if item == "p"),
        "{err:?}"
    );
    assert!(!out.0.exists());
}

#[test]
fn unwritable_output_directory_is_an_io_error() {
    let out = OutDir::new("io");
    std::fs::create_dir_all(&out.0).unwrap();
    let file = out.0.join("not-a-directory");
    std::fs::write(&file, b"x").unwrap();
    let err = joints_plot().render(&file.join("sub"), "f").unwrap_err();
    assert!(
        matches!(&err, PlotError::Io { path, .. } if *path == file.join("sub")),
        "{err:?}"
    );
}

// --- Paper-ready figures (issue 45): grey-scale styles, legend, labels, border, size and resolution. ---

/// `(stroke colour, points)` of every `<polyline>` of an SVG written by plotters.
pub(crate) fn svg_polylines(svg: &str) -> Vec<(String, Vec<(f64, f64)>)> {
    let attr = |tag: &str, name: &str| -> String {
        let start = tag.find(&format!(" {name}=\"")).unwrap() + name.len() + 3;
        let len = tag[start..].find('"').unwrap();
        tag[start..start + len].to_owned()
    };
    svg.split("<polyline ")
        .skip(1)
        .map(|chunk| {
            let tag = format!(" {}", chunk.split("/>").next().unwrap());
            let points = attr(&tag, "points")
                .split_whitespace()
                .map(|p| {
                    let (x, y) = p.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect();
            (attr(&tag, "stroke"), points)
        })
        .collect()
}

/// The boxes `(left, top, right, bottom)` of the texts `labels` in an SVG written by plotters, as drawn by the
/// event labels (centred, bottom-anchored, [`EVENT_FONT_PX`] at scale 1): widths from the embedded font.
pub(crate) fn event_label_boxes(svg: &str, labels: &[&str]) -> Vec<(f64, f64, f64, f64)> {
    ensure_font().unwrap();
    let mut buffer = String::new();
    let area = SVGBackend::with_string(&mut buffer, DEFAULT_SIZE).into_drawing_area();
    let style = Look { scale: 1.0 }.font(EVENT_FONT_PX);
    let texts = svg_texts(svg);
    labels
        .iter()
        .map(|label| {
            let (x, y) = text_position(&texts, label);
            let width = f64::from(area.estimate_text_size(label, &style).unwrap().0);
            (x - width / 2.0, y - EVENT_FONT_PX, x + width / 2.0, y)
        })
        .collect()
}

/// Fails when two boxes `(left, top, right, bottom)` intersect.
pub(crate) fn assert_disjoint(boxes: &[(f64, f64, f64, f64)], labels: &[&str]) {
    for i in 0..boxes.len() {
        for j in i + 1..boxes.len() {
            let (a, b) = (boxes[i], boxes[j]);
            let apart = a.2 <= b.0 || b.2 <= a.0 || a.3 <= b.1 || b.3 <= a.1;
            assert!(
                apart,
                "labels {:?} {a:?} and {:?} {b:?} overlap",
                labels[i], labels[j]
            );
        }
    }
}

mod style;
