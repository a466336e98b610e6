//! The report's tests: the printed table, and the figures of the reference run.

mod printed {
    use super::super::*;

    #[test]
    fn the_printed_table_explains_every_column() {
        let summary = Summary {
            scenario: "s".into(),
            runs: Vec::new(),
        };
        let text = summary.to_string();
        let header = text.lines().nth(1).unwrap_or_default();
        for column in [
            "iter",
            "joint",
            "max jump",
            "max step",
            "final ‖e‖",
            "margin",
            "events",
        ] {
            assert!(header.contains(column), "{column:?} not in {header:?}");
            assert!(
                text.contains(&format!("{column} = ")),
                "{column:?} not explained"
            );
        }
        assert!(text.contains("docs/guide/reading_results.md"));
    }
}

#[cfg(feature = "plot")]
mod figures {
    use super::super::figures::{errors_figure, image_figure, joints_figure};
    use super::super::*;
    use crate::plot::tests::{assert_disjoint, event_label_boxes, svg_texts, OutDir};
    use crate::plot::FigureStyle;
    use crate::scenario::Experiment;

    /// The full method on the reference scenario: its experiment and run.
    fn full_method() -> (Experiment<6>, Run<6>) {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/assets/scenarios/paper_afma6.toml"
        );
        let scenario = Scenario::from_file(Path::new(path)).unwrap();
        let experiment = scenario.experiment::<6>().unwrap();
        let run = experiment
            .run(&scenario.settings(), RunKind::FullMethod)
            .unwrap();
        (experiment, run)
    }

    /// Renders the figures of the full method and checks them on what they show.
    #[test]
    fn full_method_figures_are_paper_ready() {
        let (experiment, run) = full_method();
        let desired = experiment
            .scene
            .view_from(&experiment.desired_camera_from_target)
            .unwrap()
            .points;
        let names = experiment.scene.chain().joint_names();
        let context = FigureContext {
            intrinsics: experiment.scene.intrinsics(),
            desired: &desired,
            joint_names: &names,
            reserve_task: Some(run.task_names.len() - 1),
            style: FigureStyle::default(),
        };

        // Time in seconds: the x axis spans the run's duration, iterations × Δt; the events sit at their time.
        let duration = run.iterations() as f64 * run.period;
        assert!((duration - 27.77).abs() < 1e-9, "{duration}");
        let joints = joints_figure(&run, "full", &context);
        assert_eq!(joints.x_label, "time (s)");
        assert_eq!(joints.x_range, Some((0.0, duration)));
        let errors = errors_figure(&run, "full", &context);
        assert_eq!(errors.x_range, Some((0.0, duration)));
        for series in joints.series.iter().chain(&errors.series) {
            let last = series.points.last().unwrap().0;
            assert!((last - (duration - run.period)).abs() < 1e-9, "{last}");
        }
        let times: Vec<f64> = joints.markers.iter().map(|m| m.x).collect();
        let expected: Vec<f64> = run
            .events
            .iter()
            .filter(|e| e.iteration > 0)
            .map(|e| e.iteration as f64 * run.period)
            .collect();
        assert_eq!(times.len(), expected.len());
        for (t, e) in times.iter().zip(&expected) {
            assert!((t - e).abs() < 1e-9, "{t} vs {e}");
        }

        let out = OutDir::new("report-full-method");
        let files = write_figures(&run, "full", context, &out.0).unwrap();
        let svg = |stem: &str| {
            let file = files
                .iter()
                .find(|f| f.svg.ends_with(format!("{stem}.svg")));
            std::fs::read_to_string(&file.unwrap().svg).unwrap()
        };
        let has_text = |svg: &str, text: &str| svg_texts(svg).iter().any(|t| t.2 == text);

        // Joints by their URDF names, not q0…q5.
        let joints_svg = svg("full_joints");
        for name in &names {
            assert!(
                has_text(&joints_svg, name),
                "joint {name:?} not in the legend"
            );
        }
        assert!(!has_text(&joints_svg, "q0"));
        assert!(has_text(&joints_svg, "time (s)"));
        // Limit and activation: two legend entries.
        assert!(has_text(&joints_svg, "limit"));
        assert!(has_text(&joints_svg, "activation (ρ = 0.1)"));

        // The close events of this run (1, 2, 3 and 3.51 s on 27.8 s) get labels that do not overlap.
        let labels: Vec<&str> = joints.markers.iter().map(|m| m.label.as_str()).collect();
        assert!(labels.len() >= 5, "{labels:?}");
        assert_disjoint(&event_label_boxes(&joints_svg, &labels), &labels);

        // The reserve task is named as such and explained.
        let errors_svg = svg("full_errors");
        let reserve = format!("{} (reserve)", run.task_names.last().unwrap());
        assert!(has_text(&errors_svg, &reserve), "{reserve:?}");
        assert!(errors_svg.contains("D23"), "the note cites D23");

        // The image border: 640 × 480 px in the legend, inside the plotted range.
        let image = image_figure(&run, "full", &context);
        let border = image.border.as_ref().unwrap();
        assert_eq!((border.x, border.y), ((0.0, 640.0), (0.0, 480.0)));
        assert!(has_text(&svg("full_image"), "image 640 × 480 px"));
    }
}
