//! Which frames each depth served the path's probes in: the probes lie near the camera,
//! where the finest nodes serve once built, so a coarser depth serves them only while
//! those are still to come, and its figures may be one frame's.

use serde::Serialize;

/// The frames one depth served probes in.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Served {
    /// Probes it served over the path.
    pub probes: u64,
    /// Frames it served any in.
    pub frames: u32,
    /// The frame it served the most in, and how many there.
    pub most_frame: u32,
    /// Probes it served in [`Served::most_frame`].
    pub most: u64,
}

impl Served {
    /// From the probes a depth served in each frame.
    pub(super) fn of(per_frame: &[u64]) -> Self {
        let (most_frame, most) = per_frame
            .iter()
            .copied()
            .enumerate()
            .max_by_key(|&(f, n)| (n, std::cmp::Reverse(f)))
            .unwrap_or_default();
        Self {
            probes: per_frame.iter().sum(),
            frames: per_frame.iter().filter(|&&n| n > 0).count() as u32,
            most_frame: most_frame as u32,
            most,
        }
    }
}

/// Counts one probe of depth `d` in frame `f` (`per_depth[d][f]`, grown as needed).
pub(super) fn count(per_depth: &mut Vec<Vec<u64>>, d: usize, f: u32) {
    if per_depth.len() <= d {
        per_depth.resize(d + 1, Vec::new());
    }
    let per_frame = &mut per_depth[d];
    if per_frame.len() <= f as usize {
        per_frame.resize(f as usize + 1, 0);
    }
    per_frame[f as usize] += 1;
}

/// Which frames each depth's probes came from (a coarse depth near the camera serves
/// while the finer nodes there are still to come: its figures may be one frame's).
pub(super) fn line(served: &[Served]) -> String {
    let parts: Vec<String> = served
        .iter()
        .enumerate()
        .filter(|(_, v)| v.probes > 0)
        .map(|(d, v)| {
            format!(
                "depth {d} {} probes in {} frame{} ({:.0} % of them in frame {})",
                v.probes,
                v.frames,
                if v.frames == 1 { "" } else { "s" },
                100.0 * v.most as f64 / v.probes as f64,
                v.most_frame
            )
        })
        .collect();
    format!(
        "  the frames each depth served probes in: {}\n",
        parts.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A depth's frames: the count of frames with any probe, and the earliest frame of
    /// the most.
    #[test]
    fn served_frames_have_known_answers() {
        let v = Served::of(&[11200, 0, 12, 12, 0, 30]);
        assert_eq!(
            v,
            Served {
                probes: 11254,
                frames: 4,
                most_frame: 0,
                most: 11200
            }
        );
        assert_eq!(Served::of(&[0, 5, 5]).most_frame, 1);
        assert_eq!(Served::of(&[]), Served::default());
        let mut per_depth = Vec::new();
        for (d, f) in [(2, 0), (2, 0), (2, 3), (1, 1)] {
            count(&mut per_depth, d, f);
        }
        assert_eq!(per_depth, vec![vec![], vec![0, 1], vec![2, 0, 0, 1]]);
    }

    #[test]
    fn the_line_names_each_depth_that_served() {
        let l = line(&[
            Served::default(),
            Served::of(&[4800]),
            Served::of(&[11200, 0, 66]),
        ]);
        assert_eq!(
            l,
            "  the frames each depth served probes in: depth 1 4800 probes in 1 frame (100 % of them in frame 0), depth 2 11266 probes in 2 frames (99 % of them in frame 0)\n"
        );
    }
}
