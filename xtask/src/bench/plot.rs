//! `bench.png`: error against time, log-log, one panel per scene, one series per method.

use std::path::Path;

use anyhow::{Context, Result};
use plotters::prelude::*;

use super::Report;

/// Registers a system sans-serif font for the labels (plotters' `ab_glyph` backend needs
/// one); false when none is found (the plot is then drawn without text).
pub fn register_font() -> bool {
    const PATHS: [&str; 4] = [
        "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
        "/usr/share/fonts/TTF/DejaVuSans.ttf",
        "/usr/share/fonts/dejavu/DejaVuSans.ttf",
        "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    ];
    for p in PATHS {
        if let Ok(bytes) = std::fs::read(p) {
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                return true;
            }
        }
    }
    false
}

/// A plotting error as an `anyhow` error.
pub fn err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow::anyhow!("plotting: {e}")
}

/// An RGB8 picture of `w × h` written to `path` as PNG.
pub fn save_rgb(buf: &[u8], (w, h): (u32, u32), path: &Path) -> Result<()> {
    image::save_buffer(path, buf, w, h, image::ColorType::Rgb8)
        .with_context(|| format!("writing {}", path.display()))
}

/// A line through `points`, a dot on each, and (with a `label`) its legend entry.
pub fn line_with_points<'a, DB, X, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    points: &[(X::ValueType, Y::ValueType)],
    style: ShapeStyle,
    label: Option<String>,
) -> Result<()>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    X: Ranged<ValueType: Clone + 'static>,
    Y: Ranged<ValueType: Clone + 'static>,
{
    let s = chart
        .draw_series(LineSeries::new(points.to_vec(), style))
        .map_err(err)?;
    if let Some(label) = label {
        s.label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], style));
    }
    let dot = style.color.filled();
    chart
        .draw_series(points.iter().map(|p| Circle::new(p.clone(), 3, dot)))
        .map_err(err)?;
    Ok(())
}

/// The legend of a chart's labelled series, in a white box at the top right.
pub fn legend<'a, DB, X, Y>(chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>) -> Result<()>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    X: Ranged,
    Y: Ranged,
{
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(err)?;
    Ok(())
}

/// Draws the plot into `path`.
pub(super) fn error_vs_time(report: &Report, path: &Path) -> Result<()> {
    let text = register_font();
    if !text {
        println!(
            "no DejaVu/Liberation font found: bench.png has no labels (apt-get install fonts-dejavu-core)"
        );
    }
    let mut scenes: Vec<&str> = Vec::new();
    for r in &report.rows {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    let cols = 3usize;
    let rows = scenes.len().div_ceil(cols).max(1);
    let (w, h) = (1500u32, 420 * rows as u32);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let panels = root.split_evenly((rows, cols));
        for (scene, area) in scenes.iter().zip(panels.iter()) {
            let pts = |m: &str| -> Vec<(f64, f64)> {
                report
                    .rows
                    .iter()
                    .filter(|r| r.scene == *scene && r.method == m && r.rel_rmse_avg > 0.0)
                    .map(|r| (r.seconds * 1e3, r.rel_rmse_avg))
                    .collect()
            };
            let all: Vec<(f64, f64)> = ["sweep-cpu", "sweep-gpu", "monte-carlo"]
                .iter()
                .flat_map(|m| pts(m))
                .collect();
            if all.is_empty() {
                continue;
            }
            let (tmin, tmax) = all
                .iter()
                .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.0), b.max(p.0)));
            let (emin, emax) = all
                .iter()
                .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)));
            let mut chart = ChartBuilder::on(area);
            chart.margin(12);
            if text {
                chart
                    .caption(*scene, ("sans-serif", 22))
                    .x_label_area_size(36)
                    .y_label_area_size(56);
            }
            let mut chart = chart
                .build_cartesian_2d(
                    (tmin * 0.5..tmax * 2.0).log_scale(),
                    (emin * 0.5..emax * 2.0).log_scale(),
                )
                .map_err(err)?;
            if text {
                chart
                    .configure_mesh()
                    .x_desc("time (ms)")
                    .y_desc("rel. RMSE of average light")
                    .x_label_formatter(&|v| format!("{v:.3}"))
                    .y_label_formatter(&|v| format!("{v:.3}"))
                    .light_line_style(WHITE)
                    .label_style(("sans-serif", 13))
                    .draw()
                    .map_err(err)?;
            }
            for (m, colour) in [
                ("sweep-cpu", BLUE),
                ("sweep-gpu", GREEN),
                ("monte-carlo", RED),
            ] {
                let mut p = pts(m);
                if p.is_empty() {
                    continue;
                }
                p.sort_by(|a, b| a.0.total_cmp(&b.0));
                let series = chart
                    .draw_series(
                        p.iter()
                            .map(|&(x, y)| Circle::new((x, y), 4, colour.filled())),
                    )
                    .map_err(err)?;
                if text {
                    series
                        .label(m)
                        .legend(move |(x, y)| Circle::new((x + 8, y), 4, colour.filled()));
                }
                if m == "monte-carlo" {
                    chart
                        .draw_series(LineSeries::new(p.clone(), colour))
                        .map_err(err)?;
                }
            }
            if text {
                legend(&mut chart)?;
            }
        }
        root.present().map_err(err)?;
    }
    save_rgb(&buf, (w, h), path)
}
