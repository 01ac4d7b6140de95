//! `cargo xtask frame`'s report as text (`frame.txt`, and what the README's figures
//! quote from it).

use super::*;

/// Of `frames`, how many swept at least 90 % of the point budget `budget` (frames the
/// budget held, not the camera's needs), and the mean points swept a frame.
fn budget_use(frames: &[FrameRow], budget: u64) -> (usize, f64) {
    let held = frames
        .iter()
        .filter(|f| f.points_swept as f64 >= 0.9 * budget as f64)
        .count();
    let mean =
        frames.iter().map(|f| f.points_swept as f64).sum::<f64>() / frames.len().max(1) as f64;
    (held, mean)
}

/// The provisional nodes frame by frame and the finest depth's sky nesting error over
/// the frames it served probes in: how far the point budget lets the nodes near the
/// camera wait for the coarser ones their boundaries read.
fn starvation_line(frames: &[FrameRow]) -> String {
    let n = frames.len().max(1) as f64;
    let mean = frames.iter().map(|f| f.provisional as f64).sum::<f64>() / n;
    let most = frames.iter().map(|f| f.provisional).max().unwrap_or(0);
    let mut rmse: Vec<f64> = frames
        .iter()
        .filter(|f| f.finest_error.sky.n > 0)
        .map(|f| f.finest_error.sky.rmse * 100.0)
        .collect();
    rmse.sort_by(f64::total_cmp);
    let spread = match (rmse.first(), rmse.get(rmse.len() / 2), rmse.last()) {
        (Some(lo), Some(mid), Some(hi)) => format!(
            "{lo:.1} / {mid:.1} / {hi:.1} % (least / median / most, over the {} frames it served probes in)",
            rmse.len()
        ),
        _ => "none (it served no probe)".to_string(),
    };
    format!(
        "  provisional nodes after a frame (swept before a coarser node their boundaries read, swept again once it is built): {mean:.1} on average, at most {most}; the finest depth's sky RMSE against the 1 m sweep frame by frame: {spread}"
    )
}

/// `, N ms CPU` where the CPU time is known.
fn cpu_note(ms: Option<f64>) -> String {
    ms.map(|c| format!(", {c:.0} ms CPU")).unwrap_or_default()
}

pub(super) fn run_line(r: &Run) -> String {
    format!(
        "sun {:>4.0}°: {:6.1} ms a frame (max {:6.1}{}), sky bias {:+6.1} % RMSE {:5.1} %, sun bias {:+6.1} % RMSE {:5.1} %, both bias {:+6.1} % RMSE {:5.1} %",
        r.elevation,
        r.mean_ms,
        r.max_ms,
        r.over_budget.map_or(String::new(), |n| format!(
            "; {n} of {} over twice the budget, {} with the host's steal taken out",
            r.frames.len(),
            r.over_budget_own.unwrap_or(n),
        )),
        r.error.sky.bias * 100.0,
        r.error.sky.rmse * 100.0,
        r.error.sun.bias * 100.0,
        r.error.sun.rmse * 100.0,
        r.error.both.bias * 100.0,
        r.error.both.rmse * 100.0,
    )
}

/// How the run's scattered sun was swept, for the report's first line.
fn scattered_sun(report: &FrameReport) -> &'static str {
    if report.sun_with_sky {
        "the sun's first collisions swept with the sky (the hierarchy's sky columns hold sky and scattered sun, its sun columns the direct sun: only both and the direct sun compare)"
    } else if report.skip_finest_sun {
        "the finest depth's scattered sun the coarser grids'"
    } else {
        "the finest depth's scattered sun swept"
    }
}

/// The report's first line: what ran, and the reference.
fn header(report: &FrameReport) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "cargo xtask frame: {} sweeper, {}-point nodes (sky sweeps with an apron of {} cells, sun responses {}), {} passes at most (tolerance {}, {} medium rule{}{}{}), {} path, bare-ground skip {}, sun's casters {}, {}, {}, side halos from {}, {}; reference {} points (one 1 m sweep, sky in {:.2} s)",
        report.sweeper,
        report.node_points,
        report.apron,
        report.sun_apron,
        report.passes,
        report.tolerance,
        report.medium,
        if report.gather {
            ", the sun's first scatterings gathered"
        } else {
            ""
        },
        if report.halo_paths {
            ", the halo's paths traced"
        } else {
            ""
        },
        match report.halo_cells.as_str() {
            "off" => ", the halo's cells taken as empty".to_string(),
            m => format!(", the halo's cells from the {m} material"),
        },
        report.path,
        if report.bare_skip { "on" } else { "off" },
        if report.no_casters { "skipped" } else { "on" },
        scattered_sun(report),
        if report.horizon {
            "horizon halves kept"
        } else {
            "horizontal bins read as even"
        },
        match (report.neighbour_halo, report.ground_lift) {
            (true, true) =>
                "the nodes before them where built (the coarser grids clear of their ground band near bare ground)",
            (true, false) => "the nodes before them where built",
            (false, true) => "the coarser grids (clear of their ground band near bare ground)",
            (false, false) => "the coarser grids (where they are near bare ground too)",
        },
        report
            .budget_ms
            .map_or("no time budget".to_string(), |ms| format!(
                "time budget {ms} ms{}",
                if report.march_before_casters {
                    " (new nodes marched before their casters)"
                } else {
                    ""
                }
            ))
            + if report.colour_band {
                ", the ground's partly covered cells of its colour (GroundBand::Colour)"
            } else {
                ""
            },
        report.reference_points,
        report.reference_sky_s
    );
    s
}

/// The report as text.
pub fn text(report: &FrameReport) -> String {
    use std::fmt::Write;
    let mut s = header(report);
    for r in &report.runs {
        let _ = writeln!(s, "\n{}", run_line(r));
        let n = r.frames.len().max(1) as f64;
        let mean = |f: fn(&StageMs) -> f64| r.frames.iter().map(|x| f(&x.ms)).sum::<f64>() / n;
        let _ = writeln!(
            s,
            "  mean ms: material {:.1}, sky boundary {:.1}, sky sweep {:.1}, sun boundary {:.1}, sun sweep {:.1}, other {:.1}, sampling {:.1}; total {:.1}",
            mean(|m| m.material),
            mean(|m| m.boundary),
            mean(|m| m.sky_sweep),
            mean(|m| m.sun_boundary),
            mean(|m| m.sun_sweep),
            mean(|m| m.other),
            mean(|m| m.sampling),
            mean(|m| m.total),
        );
        if let Some(b) = report.budget_ms.map(f64::from) {
            for f in r.frames.iter().filter(|f| f.ms.total > 2.0 * b) {
                let ms = |v: Option<f64>| v.map_or("?".to_string(), |v| format!("{v:.0}"));
                let _ = writeln!(
                    s,
                    "  over twice the budget: frame {} {:.1} ms; this process's threads ran {} ms and waited {} ms for a core, the hypervisor's steal {} ms over all cores; {} pages first touched",
                    f.frame,
                    f.ms.total,
                    ms(f.host.ran_ms),
                    ms(f.host.waited_ms),
                    ms(f.host.steal_ms),
                    f.host
                        .page_faults
                        .map_or("?".to_string(), |n| n.to_string()),
                );
            }
        }
        if let Some(steal) = r.steal_ms {
            let waited: f64 = r.frames.iter().filter_map(|f| f.host.waited_ms).sum();
            let _ = writeln!(
                s,
                "  the machine's share over the path: the hypervisor's steal {steal:.0} ms over all cores, this process's threads waiting for a core {waited:.0} ms"
            );
        }
        let _ = writeln!(
            s,
            "  load {:.2} s; points swept per second: {:.3} M of frame time, {:.3} M of sweeping time; the kernel alone on the path's own sweeps {:.3} M (frame time's rate {:.2} of the kernel's)",
            r.load_s,
            r.points_per_s_frame / 1e6,
            r.points_per_s_sweeping / 1e6,
            r.points_per_s_kernel / 1e6,
            r.points_per_s_frame / r.points_per_s_kernel.max(1e-9)
        );
        let casters: u32 = r.frames.iter().map(|f| f.casters).sum();
        let held_mb = r.frames.iter().map(|f| f.caster_bytes).max().unwrap_or(0) as f64 / 1e6;
        let _ = writeln!(
            s,
            "  sun casters (nodes composed for the march alone): {casters} over the path, {:.1} a frame, at most {held_mb:.1} MB held",
            casters as f64 / n
        );
        let (held, mean) = budget_use(&r.frames, report.budget_points);
        let _ = writeln!(
            s,
            "  point budget {} a frame: {mean:.0} points swept a frame on average, {held} of {} frames held by it (90 % of it or more swept): their time is the budget's points times a point's cost",
            report.budget_points,
            r.frames.len()
        );
        let _ = writeln!(s, "{}", starvation_line(&r.frames));
        if r.sun_move_wait_frames > 0 || r.sun_move_world_ms < 0.5 * r.sun_move_landed_ms {
            let _ = writeln!(
                s,
                "  sun +20°: set_sun {:.1} ms{} (the direct sun of {} grids re-marched), the world grid's scattered sun on a thread: {} frames of the old one (max {:.0} ms) until it landed {:.0} ms later; that frame {:.0} ms ({} sun responses, {} left)",
                r.sun_move_world_ms,
                cpu_note(r.sun_move_cpu_ms),
                r.sun_move_marched,
                r.sun_move_wait_frames,
                r.sun_move_wait_max_ms,
                r.sun_move_landed_ms,
                r.sun_move_frame_ms,
                r.sun_move_built,
                r.sun_move_pending
            );
        } else {
            let _ = writeln!(
                s,
                "  sun +20°: set_sun {:.0} ms{} (the direct sun of {} grids re-marched, the world grid's scattered sun swept), next frame {:.0} ms ({} sun responses, {} left)",
                r.sun_move_world_ms,
                cpu_note(r.sun_move_cpu_ms),
                r.sun_move_marched,
                r.sun_move_frame_ms,
                r.sun_move_built,
                r.sun_move_pending
            );
        }
        let (a, b) = (&r.sun_move_error_at_once, &r.sun_move_error_settled);
        let _ = writeln!(
            s,
            "  every wanted node's sun the new one {:.0} ms after set_sun ({} frames); RMSE % at the last camera against the reference for the new sun, as set_sun returns / settled: direct sun {:.1} / {:.1}, sun {:.1} / {:.1}, both {:.1} / {:.1}",
            r.sun_move_settled_ms,
            r.sun_move_settled_frames,
            100.0 * a.direct.rmse,
            100.0 * b.direct.rmse,
            100.0 * a.sun.rmse,
            100.0 * b.sun.rmse,
            100.0 * a.both.rmse,
            100.0 * b.both.rmse,
        );
        if let Some(m) = &r.monte_carlo {
            s.push_str(&mc::lines(m, r.elevation));
        }
        s.push_str(&nesting_lines(r));
    }
    s
}

/// A run's nesting lines: the seams at the last camera, the finest depth's own sun over
/// the path, the nesting alone by depth, and the two tables by depth.
fn nesting_lines(r: &Run) -> String {
    use std::fmt::Write;
    let mut s = seams::line(&r.seams);
    let [own, coarse] = &r.finest_sun;
    let _ = writeln!(
        s,
        "  the finest depth over the path (RMSE % against the 1 m sweep): {} probes read their node's own sun (its responses, or while they wait its transmittance marched at once), sun {:.1}, direct sun {:.1}; {} ({:.0} %) a coarser grid's sun while their node's was still to come, sun {:.1}, direct sun {:.1}",
        own.both.n,
        100.0 * own.sun.rmse,
        100.0 * own.direct.rmse,
        coarse.both.n,
        100.0 * coarse.both.n as f64 / (own.both.n + coarse.both.n).max(1) as f64,
        100.0 * coarse.sun.rmse,
        100.0 * coarse.direct.rmse
    );
    s.push_str(&super::places::lines(&r.finest_places));
    s.push_str(&super::bins::line(&r.finest_bins));
    let by_depth: Vec<String> = r
        .error_by_depth_own
        .iter()
        .enumerate()
        .filter(|(_, e)| e.both.n > 0)
        .map(|(d, e)| {
            format!(
                "depth {d} {:.1} / {:.1} / {:.1}",
                100.0 * e.sky.rmse,
                100.0 * e.sun.rmse,
                100.0 * e.both.rmse
            )
        })
        .collect();
    let _ = writeln!(
        s,
        "  nesting alone at sun {:.0}° (RMSE % of sky / sun / both against one sweep at each depth's own cell): {}",
        r.elevation,
        by_depth.join(", ")
    );
    s.push_str(&super::served::line(&r.served));
    s.push_str(&super::far::line(&r.far, r.elevation));
    let _ = writeln!(
        s,
        "  nesting alone at sun {:.0}°, the largest error over the local brightest value (% of sky / sun / both; sun and both away from shadow edges): {}",
        r.elevation,
        peak_list(&r.peaks, true)
    );
    let _ = writeln!(
        s,
        "  the same over the path's second half (the cold start's first frames left out): {}",
        peak_list(&r.peaks_second_half, false)
    );
    if let Some(p) = r.peaks.last() {
        s.push_str(&worst_lines(p));
    }
    depth_table(&mut s, "against the 1 m sweep", &r.error_by_depth, |d| {
        format!("{d:5}")
    });
    depth_table(
        &mut s,
        "against one sweep at the depth's own cell (the nesting alone)",
        &r.error_by_depth_own,
        |d| format!("{d:5}"),
    );
    s
}

/// A table of errors by the depth serving the points (depths with none left out).
/// The depths' peaks (`frame/peaks.rs`), each with its 99.9th percentile and, with
/// `edges`, the share of its probes at shadow edges.
fn peak_list(peaks: &[super::Peaks], edges: bool) -> String {
    let list: Vec<String> = (peaks.iter().enumerate())
        .filter(|(_, p)| p.probes > 0)
        .map(|(d, p)| {
            let at_edges = if edges {
                format!(
                    "; {:.1} % of its probes at edges",
                    100.0 * p.at_edges as f64 / p.probes as f64
                )
            } else {
                String::new()
            };
            format!(
                "depth {d} {} (99.9th percentile {}{at_edges})",
                percents(p.max),
                percents(p.p999)
            )
        })
        .collect();
    list.join(", ")
}

/// Three shares as percentages, `a / b / c` (sky / sun / both).
/// Where the finest depth's largest errors of sky, sun and both lie, and what each side
/// read there.
fn worst_lines(p: &super::Peaks) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    for (name, w) in ["sky", "sun", "both"].iter().zip(&p.worst) {
        let Some(w) = w else { continue };
        let facing = match w.facing {
            [x, y, z] if y > 0.5 => format!("facing up (normal {x:.2}, {y:.2}, {z:.2})"),
            [_, y, _] if y < -0.5 => "facing down".to_string(),
            [x, _, z] => format!("facing ({x:.0}, 0, {z:.0})"),
        };
        let kind = if w.vertex {
            "terrain vertex"
        } else {
            "volume point"
        };
        let [x, y, z] = w.at;
        let _ = writeln!(
            s,
            "    the finest depth's largest {name} error, {:.1} %: frame {}, {kind} at ({x:.1}, {y:.1}, {z:.1}) {facing}, {:.1} cells from its grid's {} side; the hierarchy {:.4} against {:.4} (the brightest near it {:.4}; the reference's direct sun there {:.4})",
            100.0 * w.relative,
            w.frame,
            w.cells_from_side,
            w.side,
            w.hierarchy,
            w.reference,
            w.brightest,
            w.direct,
        );
    }
    s
}

fn percents(v: [f32; 3]) -> String {
    v.map(|x| format!("{:.1}", 100.0 * x)).join(" / ")
}

fn depth_table(s: &mut String, title: &str, by_depth: &[Errors], depth: impl Fn(usize) -> String) {
    use std::fmt::Write;
    let _ = writeln!(
        s,
        "  {title}:\n  depth | points | sky bias / RMSE % | sun bias / RMSE % | both bias / RMSE % | direct sun bias / RMSE %"
    );
    for (d, e) in by_depth.iter().enumerate() {
        if e.both.n == 0 {
            continue;
        }
        let _ = writeln!(
            s,
            "  {} | {:6} | {:+6.1} / {:5.1} | {:+6.1} / {:5.1} | {:+6.1} / {:5.1} | {:+6.1} / {:5.1}",
            depth(d),
            e.both.n,
            e.sky.bias * 100.0,
            e.sky.rmse * 100.0,
            e.sun.bias * 100.0,
            e.sun.rmse * 100.0,
            e.both.bias * 100.0,
            e.both.rmse * 100.0,
            e.direct.bias * 100.0,
            e.direct.rmse * 100.0
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frames that swept 90 % of the budget or more count as held by it; the mean is
    /// over every frame.
    #[test]
    fn budget_use_counts_the_frames_the_budget_held() {
        let row = |points_swept| FrameRow::for_test(points_swept, 0.0, None);
        let frames = [row(1000), row(900), row(899), row(0)];
        assert_eq!(budget_use(&frames, 1000), (2, 699.75));
        assert_eq!(budget_use(&[], 1000), (0, 0.0));
    }

    /// The provisional nodes' mean and most, and the finest depth's sky RMSE least /
    /// median / most over the frames where it served probes (not the others).
    #[test]
    fn starvation_line_counts_the_frames_the_finest_depth_served() {
        let row = |provisional, rmse: Option<f64>| {
            let mut r = FrameRow::for_test(0, 0.0, None);
            r.provisional = provisional;
            if let Some(rmse) = rmse {
                r.finest_error.sky = Error {
                    bias: 0.0,
                    rmse,
                    n: 10,
                };
            }
            r
        };
        let frames = [
            row(0, None),
            row(4, Some(0.03)),
            row(2, Some(0.01)),
            row(6, Some(0.02)),
        ];
        let line = starvation_line(&frames);
        assert!(line.contains("3.0 on average, at most 6"), "{line}");
        assert!(
            line.contains("1.0 / 2.0 / 3.0 % (least / median / most, over the 3 frames"),
            "{line}"
        );
        assert!(starvation_line(&[row(0, None)]).contains("it served no probe"));
    }
}
