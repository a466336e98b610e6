//! The figures' style: label placement, grey-scale series, line patterns, notes, borders and sizes.

use super::*;

#[test]
fn label_placement_never_overlaps_and_uses_the_fewest_rows() {
    // Twelve labels within 30 px, two at the edges, one far away.
    let mut items: Vec<(i32, i32)> = (0..12).map(|k| (300 + 3 * k, 60 + 5 * k)).collect();
    items.extend([(2, 80), (998, 80), (700, 50)]);
    let boxes = place_labels(&items, (0, 1000), EVENT_GAP_PX);
    for (k, b) in boxes.iter().enumerate() {
        assert_eq!(b.right - b.left, items[k].1, "width kept");
        assert!(b.left >= 0 && b.right <= 1000, "inside the bounds: {b:?}");
    }
    for (i, a) in boxes.iter().enumerate() {
        for b in &boxes[i + 1..] {
            let apart = a.right + EVENT_GAP_PX <= b.left || b.right + EVENT_GAP_PX <= a.left;
            assert!(a.row != b.row || apart, "{a:?} and {b:?} overlap");
        }
    }
    // The twelve close labels all contain column 333: twelve rows, no more; the others share row 0.
    let rows = boxes.iter().map(|b| b.row).max().unwrap() + 1;
    assert_eq!(rows, 12);
    assert!(boxes[12..].iter().all(|b| b.row == 0), "{boxes:?}");
    // A label centred on its column when there is room.
    assert_eq!(boxes[14].left + boxes[14].right, 2 * 700);
}

#[test]
fn close_event_labels_do_not_overlap_in_the_figure() {
    let out = OutDir::new("close-events");
    // The full method's events on the reference scenario (s), and two more, closer still.
    let events = [
        (1.0, "push angle"),
        (2.0, "push area"),
        (3.0, "push third_order"),
        (3.51, "remove area"),
        (12.68, "reinsert area"),
        (12.75, "escape image_points (reserve)"),
        (27.6, "remove centroid"),
    ];
    let plot = LinePlot {
        markers: events.iter().map(|&(t, l)| Marker::new(t, l)).collect(),
        x_range: Some((0.0, 27.77)),
        ..joints_plot()
    };
    let files = plot.render(&out.0, "close").unwrap();
    let svg = std::fs::read_to_string(&files.svg).unwrap();
    let labels: Vec<&str> = events.iter().map(|e| e.1).collect();
    let boxes = event_label_boxes(&svg, &labels);
    assert_disjoint(&boxes, &labels);
    // Every label above the plotting area and left of the legend.
    let legend_left = text_position(&svg_texts(&svg), "q1").0;
    let plot_top = svg_polylines(&svg)
        .iter()
        .filter(|(stroke, _)| stroke == "#6E6E6E")
        .flat_map(|(_, points)| points.iter().map(|p| p.1))
        .fold(f64::INFINITY, f64::min);
    for (b, label) in boxes.iter().zip(&labels) {
        assert!(b.0 >= 0.0 && b.2 < legend_left, "{label:?} {b:?} outside");
        assert!(b.3 <= plot_top, "{label:?} {b:?} below the top {plot_top}");
    }
}

#[test]
fn series_styles_differ_without_colour() {
    let styles: Vec<SeriesStyle> = (0..20).map(SeriesStyle::nth).collect();
    for (i, a) in styles.iter().enumerate() {
        for b in &styles[i + 1..] {
            assert!(
                (a.pattern, a.marker) != (b.pattern, b.marker),
                "{a:?} and {b:?} differ in colour only"
            );
        }
        assert_ne!(
            a.pattern,
            LinePattern::Dotted,
            "dotted is for reference lines"
        );
    }
    assert_eq!(styles[0].color, PALETTE[0]);
}

#[test]
fn dashes_follow_the_pattern_across_vertices() {
    // 9 on, 5 off along a polyline bending at x = 12.
    let pieces = dash(&[(0.0, 0.0), (12.0, 0.0), (12.0, 18.0)], &[9.0, 5.0]);
    let expected: Vec<Vec<Px>> = vec![
        vec![(0.0, 0.0), (9.0, 0.0)],
        vec![(12.0, 2.0), (12.0, 11.0)],
        vec![(12.0, 16.0), (12.0, 18.0)],
    ];
    assert_eq!(pieces.len(), expected.len(), "{pieces:?}");
    for (piece, want) in pieces.iter().zip(&expected) {
        let (first, last) = (piece[0], piece[piece.len() - 1]);
        assert_relative_eq!(first.0, want[0].0, epsilon = 1e-12);
        assert_relative_eq!(first.1, want[0].1, epsilon = 1e-12);
        assert_relative_eq!(last.0, want[1].0, epsilon = 1e-12);
        assert_relative_eq!(last.1, want[1].1, epsilon = 1e-12);
    }
    // The dash crossing the vertex keeps the vertex.
    let bent = dash(&[(0.0, 0.0), (5.0, 0.0), (5.0, 5.0)], &[9.0, 5.0]);
    assert_eq!(bent, vec![vec![(0.0, 0.0), (5.0, 0.0), (5.0, 4.0)]]);
    // Solid: the whole line.
    assert_eq!(dash(&[(0.0, 0.0), (3.0, 4.0)], &[]).len(), 1);
}

#[test]
fn markers_are_spaced_along_x() {
    // A step: markers every 10 px of x from 5, none bunched on the vertical part.
    let step = [(0.0, 0.0), (20.0, 0.0), (20.0, 100.0), (40.0, 100.0)];
    let at = points_along(&step, 10.0, 5.0);
    let xs: Vec<f64> = at.iter().map(|p| p.0).collect();
    assert_eq!(xs, [5.0, 15.0, 25.0, 35.0]);
}

/// The polylines drawn in the legend row of the text `label` (within half a row of its centre, left of it).
fn legend_row_polylines(svg: &str, label: &str) -> Vec<Vec<(f64, f64)>> {
    let (x, y) = text_position(&svg_texts(svg), label);
    svg_polylines(svg)
        .into_iter()
        .map(|(_, points)| points)
        .filter(|points| {
            points.iter().all(|p| {
                (p.1 - y).abs() < f64::from(LEGEND_ROW_PX) / 2.0
                    && p.0 < x
                    && p.0 >= x - f64::from(LEGEND_SWATCH_PX) - 1.0
            })
        })
        .collect()
}

#[test]
fn limit_and_activation_lines_have_distinct_legend_styles() {
    let plot = LinePlot {
        horizontal_lines: vec![
            HorizontalLine::new(0.0, "limit").with_pattern(LinePattern::Solid),
            HorizontalLine::new(1.0, "limit").with_pattern(LinePattern::Solid),
            HorizontalLine::new(0.1, "activation").with_pattern(LinePattern::Dotted),
            HorizontalLine::new(0.9, "activation").with_pattern(LinePattern::Dotted),
        ],
        ..joints_plot()
    };
    let prepared = plot.prepare().unwrap();
    let legend = prepared.legend();
    let swatch = |label: &str| {
        let found: Vec<Swatch> = legend
            .iter()
            .filter(|e| e.label == label)
            .map(|e| e.swatch)
            .collect();
        assert_eq!(found.len(), 1, "one legend entry for {label:?}");
        found[0]
    };
    assert_ne!(swatch("limit"), swatch("activation"));
    // In the figure: the limit's swatch is one stroke, the activation's a row of dots.
    let out = OutDir::new("limit-activation");
    let svg = std::fs::read_to_string(plot.render(&out.0, "j").unwrap().svg).unwrap();
    assert_eq!(legend_row_polylines(&svg, "limit").len(), 1);
    assert!(legend_row_polylines(&svg, "activation").len() >= 5);
    // Each series' swatch shows its pattern: q1 solid (one stroke), q2 dashed (several).
    assert_eq!(legend_row_polylines(&svg, "q1").len(), 1);
    assert!(legend_row_polylines(&svg, "q2").len() >= 2);
}

#[test]
fn notes_are_wrapped_below_the_legend() {
    let note = "reserve: a task held back, pushed in place of the last task only to leave a false \
                equilibrium (event escape, D23).";
    let plot = LinePlot {
        notes: vec![note.into()],
        ..joints_plot()
    };
    let out = OutDir::new("notes");
    let svg = std::fs::read_to_string(plot.render(&out.0, "n").unwrap().svg).unwrap();
    let texts = svg_texts(&svg);
    let last_entry = text_position(&texts, "joint limits");
    let lines: Vec<&(f64, f64, String)> = texts
        .iter()
        .filter(|t| {
            let legend_left = last_entry.0 - f64::from(LEGEND_SWATCH_PX) - 1.0;
            t.1 > last_entry.1 && (legend_left..last_entry.0).contains(&t.0)
        })
        .collect();
    assert!(lines.len() >= 2, "wrapped: {lines:?}");
    let joined: Vec<&str> = lines.iter().map(|t| t.2.as_str()).collect();
    assert_eq!(
        joined.join(" "),
        note.split_whitespace().collect::<Vec<_>>().join(" ")
    );
}

#[test]
fn image_border_is_drawn_and_in_the_legend() {
    let plot = TrajectoryPlot {
        border: Some(Border::new((-0.3, 0.3), (-0.25, 0.25), "image border")),
        ..image_plot()
    };
    let out = OutDir::new("border");
    let files = plot.render(&out.0, "b").unwrap();
    assert_rendered(&files, DEFAULT_SIZE, &["image border"]);
    let svg = std::fs::read_to_string(&files.svg).unwrap();
    // A closed axis-aligned rectangle in the reference colour, 0.6 wide for 0.5 high on equal axes.
    let frames: Vec<Vec<(f64, f64)>> = svg_polylines(&svg)
        .into_iter()
        .filter(|(stroke, points)| stroke == "#282828" && points.len() == 5)
        .map(|(_, points)| points)
        .collect();
    assert_eq!(frames.len(), 1, "one border");
    let frame = &frames[0];
    assert_eq!(frame[0], frame[4], "closed");
    let width = frame[1].0 - frame[0].0;
    let height = frame[2].1 - frame[1].1;
    assert_relative_eq!(width / height, 0.6 / 0.5, max_relative = 0.02);
    // Invalid borders are errors.
    let bad = TrajectoryPlot {
        border: Some(Border::new((1.0, 1.0), (0.0, 1.0), "b")),
        ..image_plot()
    };
    assert_eq!(
        bad.render(&out.0, "bad").unwrap_err(),
        PlotError::InvalidRange {
            axis: "x",
            min: 1.0,
            max: 1.0
        }
    );
}

#[test]
fn scale_sets_the_png_resolution_and_keeps_the_svg() {
    let out = OutDir::new("scale");
    let plot = LinePlot {
        style: FigureStyle::default().with_scale(2.0),
        ..joints_plot()
    };
    let files = plot.render(&out.0, "s").unwrap();
    let png = std::fs::read(&files.png).unwrap();
    assert_eq!(png_dimensions(&png), (2048, 1280));
    let svg = std::fs::read_to_string(&files.svg).unwrap();
    assert!(svg.contains(r#"width="1024" height="640""#));
    // The same layout: the title's font is twice as large in the PNG than at scale 1 (same SVG text positions).
    let single = plot_svg_at(1.0);
    assert_eq!(svg_texts(&single), svg_texts(&svg));

    let print = FigureStyle::for_print(3.5, 2.2, 300.0);
    assert_eq!((print.width, print.height), (630, 396));
    assert_eq!(print.png_size(), (1050, 660));
}

fn plot_svg_at(scale: f64) -> String {
    let out = OutDir::new(&format!("scale-{scale}"));
    let plot = LinePlot {
        style: FigureStyle::default().with_scale(scale),
        ..joints_plot()
    };
    std::fs::read_to_string(plot.render(&out.0, "s").unwrap().svg).unwrap()
}

#[test]
fn invalid_sizes_and_scales_are_errors() {
    let with = |style: FigureStyle| LinePlot {
        style,
        ..joints_plot()
    };
    for scale in [0.0, 0.1, f64::NAN, f64::INFINITY, 9.0] {
        let style = FigureStyle::default().with_scale(scale);
        let err = with(style)
            .render(&OutDir::new("bad-scale").0, "f")
            .unwrap_err();
        assert!(
            matches!(
                err,
                PlotError::InvalidScale {
                    width: 1024,
                    height: 640,
                    ..
                }
            ),
            "{scale}: {err:?}"
        );
    }
    let huge = FigureStyle::new(100_000, 640);
    let expected = PlotError::InvalidSize {
        width: 100_000,
        height: 640,
    };
    assert_line_error(&with(huge), "f", &expected);
    // A NaN printed size is a size of 0, refused.
    let nan = FigureStyle::for_print(f64::NAN, 2.0, 300.0);
    assert!(matches!(
        with(nan).render(&OutDir::new("nan-print").0, "f"),
        Err(PlotError::InvalidSize { width: 0, .. })
    ));
}

#[test]
fn many_close_events_are_numbered_with_a_key() {
    let out = OutDir::new("numbered");
    // Twenty events within 40 % of the run, as the obstacle scenario's full method has.
    let events: Vec<(f64, String)> = (0..20)
        .map(|k| (20.0 + 8.0 * f64::from(k), format!("remove task_{k}")))
        .collect();
    let plot = LinePlot {
        markers: events
            .iter()
            .map(|(x, l)| Marker::new(*x, l.clone()))
            .collect(),
        ..joints_plot()
    };
    let svg = std::fs::read_to_string(plot.render(&out.0, "many").unwrap().svg).unwrap();
    let numbers: Vec<String> = (1..=20).map(|k| k.to_string()).collect();
    let labels: Vec<&str> = numbers.iter().map(String::as_str).collect();
    let boxes = event_label_boxes(&svg, &labels);
    assert_disjoint(&boxes, &labels);
    // Numbered in time order: left to right.
    assert!(boxes.windows(2).all(|w| w[0].0 < w[1].0), "{boxes:?}");
    let key: String = svg_texts(&svg)
        .iter()
        .filter(|t| t.0 > boxes[19].2)
        .map(|t| t.2.replace('\u{a0}', " "))
        .collect::<Vec<_>>()
        .join(" ");
    assert!(
        key.contains("Events: 1 remove task_0 · 2 remove task_1"),
        "{key}"
    );
    assert!(key.contains("20 remove task_19."), "{key}");
}
