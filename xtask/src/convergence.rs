//! `cargo xtask exact`'s convergence part: passes and time to tolerance 1e-4 against
//! optical depth and albedo, plain and accelerated (`Acceleration::Diffusion`), as a
//! table and a picture (target/bench/convergence.png).

use std::path::Path;

use crate::bench::plot::err;
use anyhow::Result;
use lightgrid_core::{Acceleration, SweepOptions};
use lightgrid_measure::exact::{self, Case};
use plotters::prelude::*;

/// Total optical depths of the slabs (cells of optical depth 1).
pub const DEPTHS: [u32; 4] = [1, 10, 100, 1000];
/// Albedos of the slabs.
pub const ALBEDOS: [f32; 4] = [0.5, 0.9, 0.99, 0.999];

/// One slab both ways: (depth, albedo, plain, accelerated).
pub type Row = (u32, f32, Case, Case);

/// Sweeps every slab plain and accelerated, at most `max_passes` passes each.
pub fn measure(max_passes: u32) -> Result<Vec<Row>> {
    let mut rows = Vec::new();
    for depth in DEPTHS {
        for w in ALBEDOS {
            eprintln!("slab of optical depth {depth}, albedo {w}...");
            let mut o = SweepOptions::multi_bounce();
            o.max_passes = max_passes;
            o.tolerance = 1e-4;
            let plain = exact::convergence_with(depth, w, &o)?;
            o.acceleration = Acceleration::Diffusion;
            let on = exact::convergence_with(depth, w, &o)?;
            rows.push((depth, w, plain, on));
        }
    }
    Ok(rows)
}

/// Half-spaces (total optical depth 40) of albedo 0.99 and 0.999 in cells of optical
/// depth 0.05, 0.69 and 3, tolerance 1e-5, plain and accelerated: (albedo, cell
/// pass-through, plain, accelerated).
pub fn half_spaces(max_passes: u32) -> Result<Vec<(f32, f32, Case, Case)>> {
    let mut rows = Vec::new();
    for w in [0.99f32, 0.999] {
        for pass in [0.95f32, 0.5, 0.05] {
            eprintln!("half-space, albedo {w}, cell pass-through {pass}...");
            let mut o = SweepOptions::multi_bounce();
            o.max_passes = max_passes;
            o.tolerance = 1e-5;
            let plain = exact::half_space_with(w, pass, 40.0, &o)?;
            o.acceleration = Acceleration::Diffusion;
            let on = exact::half_space_with(w, pass, 40.0, &o)?;
            rows.push((w, pass, plain, on));
        }
    }
    Ok(rows)
}

/// [`half_spaces`] as a table.
pub fn half_space_table(rows: &[(f32, f32, Case, Case)]) -> String {
    let mut s = format!(
        "{:>6} {:>10} | {:>6} {:>9} {:>7} | {:>6} {:>9} {:>7}\n",
        "albedo", "cell depth", "passes", "ms", "error", "passes", "ms", "error"
    );
    for (w, pass, p, a) in rows {
        s += &format!(
            "{w:>6} {:>10.2} | {:>6} {:>9.1} {:>+6.1}% | {:>6} {:>9.1} {:>+6.1}%\n",
            -pass.ln(),
            p.passes,
            p.seconds * 1e3,
            p.error * 100.0,
            a.passes,
            a.seconds * 1e3,
            a.error * 100.0
        );
    }
    s
}

/// The rows as a table: passes and milliseconds both ways, and the albedo each found.
pub fn table(rows: &[Row]) -> String {
    let mut s = format!(
        "{:>6} {:>6} | {:>6} {:>9} {:>8} | {:>6} {:>9} {:>8}\n",
        "depth", "albedo", "passes", "ms", "reflects", "passes", "ms", "reflects"
    );
    s += &format!("{:>15}| {:^25} | {:^25}\n", "", "plain", "accelerated");
    for (d, w, p, a) in rows {
        s += &format!(
            "{d:>6} {w:>6} | {:>6} {:>9.1} {:>8.5} | {:>6} {:>9.1} {:>8.5}\n",
            p.passes,
            p.seconds * 1e3,
            p.swept,
            a.passes,
            a.seconds * 1e3,
            a.swept
        );
    }
    s
}

/// Passes (left) and time (right) against optical depth, one line per albedo and way.
pub fn plot(rows: &[Row], path: &Path) -> Result<()> {
    let text = crate::bench::plot::register_font();
    let (w, h) = (1100u32, 460u32);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let panels = root.split_evenly((1, 2));
        let colours = [BLUE, GREEN, MAGENTA, RED];
        type Pick = fn(&Case) -> f64;
        let picks: [(&str, &str, Pick); 2] = [
            ("passes to 1e-4", "passes", |c| c.passes as f64),
            ("time to 1e-4", "ms", |c| c.seconds * 1e3),
        ];
        for (panel, (title, unit, pick)) in panels.iter().zip(picks) {
            let top = rows
                .iter()
                .flat_map(|r| [pick(&r.2), pick(&r.3)])
                .fold(1.0f64, f64::max)
                * 1.5;
            let bottom = rows
                .iter()
                .flat_map(|r| [pick(&r.2), pick(&r.3)])
                .fold(f64::MAX, f64::min)
                .max(1e-3)
                / 1.5;
            let mut b = ChartBuilder::on(panel);
            b.margin(12);
            if text {
                b.caption(format!("slab, {title}"), ("sans-serif", 18))
                    .x_label_area_size(36)
                    .y_label_area_size(56);
            }
            let mut chart = b
                .build_cartesian_2d((0.7f64..1500f64).log_scale(), (bottom..top).log_scale())
                .map_err(err)?;
            if text {
                chart
                    .configure_mesh()
                    .x_desc("optical depth")
                    .y_desc(unit)
                    .draw()
                    .map_err(err)?;
            }
            for (wi, albedo) in ALBEDOS.iter().enumerate() {
                let colour = colours[wi % colours.len()];
                for accelerated in [false, true] {
                    let line: Vec<(f64, f64)> = rows
                        .iter()
                        .filter(|r| r.1 == *albedo)
                        .map(|r| {
                            let c = if accelerated { &r.3 } else { &r.2 };
                            (r.0 as f64, pick(c))
                        })
                        .collect();
                    let style = if accelerated {
                        colour.stroke_width(3)
                    } else {
                        colour.mix(0.5).stroke_width(1)
                    };
                    let label = text.then(|| {
                        format!(
                            "albedo {albedo}, {}",
                            if accelerated { "accelerated" } else { "plain" }
                        )
                    });
                    crate::bench::plot::line_with_points(&mut chart, &line, style, label)?;
                }
            }
            if text {
                chart
                    .configure_series_labels()
                    .position(SeriesLabelPosition::UpperLeft)
                    .background_style(WHITE.mix(0.8))
                    .border_style(BLACK)
                    .label_font(("sans-serif", 11))
                    .draw()
                    .map_err(err)?;
            }
        }
        root.present().map_err(err)?;
    }
    crate::bench::plot::save_rgb(&buf, (w, h), path)
}
