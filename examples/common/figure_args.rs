//! The figure options the report examples share: `--size WxH` and `--scale S` (included by `paper_experiment` and
//! `run_scenario`).

use servostack::report::ReportOptions;

/// `options` with the figure size (`--size WxH`) or PNG scale (`--scale S`) set from `value`.
#[cfg(feature = "plot")]
pub fn figure_option(
    options: ReportOptions,
    flag: &str,
    value: &str,
    usage: &'static str,
) -> Result<ReportOptions, Box<dyn std::error::Error>> {
    let mut style = options.figure_style;
    if flag == "--size" {
        let (w, h) = value.split_once('x').ok_or(usage)?;
        (style.width, style.height) = (w.parse()?, h.parse()?);
    } else {
        style.scale = value.parse()?;
    }
    Ok(options.with_figure_style(style))
}

/// Without the `plot` feature there are no figures to size.
#[cfg(not(feature = "plot"))]
pub fn figure_option(
    options: ReportOptions,
    _flag: &str,
    _value: &str,
    _usage: &'static str,
) -> Result<ReportOptions, Box<dyn std::error::Error>> {
    Ok(options)
}
