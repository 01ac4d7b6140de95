//! The finest depth's sky by the way its light travels: at the volume points the
//! finest nodes serve, the sky light of four groups of bins (travelling down, the
//! horizontal bins' downward and upward halves, travelling up), summed over the path,
//! over the 1 m sweep's sums at the same points; and the same for the one sweep at the
//! next coarser depth's cell, whose light a finest node's sides take in.
//!
//! The downward bins enter through a node's top, which nests them to 0.1–0.2 %; the
//! horizontal ones enter through its sides, and in clear air they cross the whole node
//! with what they brought. Where the hierarchy's horizontal groups sit as far from
//! the 1 m sweep as the coarser sweep's do, the finest depth's sky error is the
//! coarser cell's own (the sweep's light at 2 m against 1 m), handed over, not lost in
//! the hand-over.

use lightgrid_core::dirs::{FIRST_HORIZONTAL, HORIZONTAL_BINS};
use lightgrid_core::glam::Vec3;
use lightgrid_core::light::luminance;
use lightgrid_core::{BinLight, HorizonLight, LightField};
use lightgrid_terrain_lod::Hierarchy;
use serde::Serialize;

use super::reference::Reference;

/// The groups, in [`BinGroups`]' order.
pub(super) const GROUPS: [&str; 4] = ["down", "horizontal going down", "horizontal going up", "up"];

/// The groups' sums over the 1 m sweep's (1 where they agree).
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct BinGroups {
    /// Volume points tallied (each once, whatever its probes face).
    pub points: u64,
    /// The hierarchy's.
    pub hierarchy: [f64; 4],
    /// The one sweep at the next coarser depth's cell (`None` with a single depth).
    pub coarser_sweep: Option<[f64; 4]>,
}

/// Luminance of `b`'s groups, `down` the downward halves of its horizontal bins
/// (even halves where none are kept).
pub(super) fn groups(b: &BinLight, down: Option<&HorizonLight>) -> [f64; 4] {
    let even;
    let down = match down {
        Some(d) => d,
        None => {
            even = HorizonLight::even(b);
            &even
        }
    };
    let sum = |r: std::ops::Range<usize>| r.map(|i| luminance(b.0[i]) as f64).sum::<f64>();
    let going_down: f64 = down.0.iter().map(|v| luminance(*v) as f64).sum();
    let horizontal = sum(FIRST_HORIZONTAL..FIRST_HORIZONTAL + HORIZONTAL_BINS);
    [
        sum(0..FIRST_HORIZONTAL),
        going_down,
        horizontal - going_down,
        sum(FIRST_HORIZONTAL + HORIZONTAL_BINS..b.0.len()),
    ]
}

/// Accumulates [`BinGroups`].
#[derive(Debug, Clone, Default)]
pub(super) struct BinTally {
    points: u64,
    /// The hierarchy's, the coarser sweep's, the 1 m sweep's sums, and the 1 m sweep's
    /// over the points the coarser sweep was read at.
    sums: [[f64; 4]; 4],
    coarser: bool,
}

impl BinTally {
    /// One point's groups: the hierarchy's, the coarser sweep's (if any) and the 1 m
    /// sweep's.
    pub(super) fn add(&mut self, h: [f64; 4], coarser: Option<[f64; 4]>, r: [f64; 4]) {
        self.points += 1;
        for k in 0..4 {
            self.sums[0][k] += h[k];
            self.sums[2][k] += r[k];
        }
        if let Some(c) = coarser {
            self.coarser = true;
            for k in 0..4 {
                self.sums[1][k] += c[k];
                self.sums[3][k] += r[k];
            }
        }
    }

    pub(super) fn groups(&self) -> BinGroups {
        let ratio = |s: &[f64; 4], r: &[f64; 4]| {
            std::array::from_fn(|k| if r[k] > 0.0 { s[k] / r[k] } else { 1.0 })
        };
        BinGroups {
            points: self.points,
            hierarchy: ratio(&self.sums[0], &self.sums[2]),
            coarser_sweep: self.coarser.then(|| ratio(&self.sums[1], &self.sums[3])),
        }
    }
}

/// A reference's sky groups at `p`.
fn reference_groups(r: &Reference, p: Vec3) -> anyhow::Result<Option<[f64; 4]>> {
    let Some((bins, halves)) = r.sky.as_ref() else {
        return Ok(None);
    };
    let b = bins.light(p, None)?;
    let d = halves.as_ref().map(|h| h.sample(p)).transpose()?;
    Ok(Some(groups(&b, d.as_ref())))
}

/// Tallies the sky's groups at `points`, read from `h` (its sky alone: the sky scale
/// toggled, as the probes' parts are read), `full` (the 1 m sweep) and `coarser`.
/// Nothing where the hierarchy's bins hold the scattered sun with the sky
/// (`HierarchyParams::sun_with_sky`: the sky is not apart there).
pub(super) fn tally(
    tally: &mut BinTally,
    h: &mut Hierarchy,
    points: &[Vec3],
    (full, coarser): (&Reference, Option<&Reference>),
) -> anyhow::Result<()> {
    if points.is_empty() || h.params().sun_with_sky {
        return Ok(());
    }
    let read = |h: &Hierarchy| -> anyhow::Result<Vec<(BinLight, Option<HorizonLight>)>> {
        points
            .iter()
            .map(|&p| Ok((h.light(p, None)?, h.horizon(p, None)?)))
            .collect()
    };
    let lit = read(h)?;
    h.set_sky_scale(Vec3::ZERO)?;
    let sun = read(h);
    h.set_sky_scale(Vec3::ONE)?;
    for (&p, ((lb, lh), (sb, sh))) in points.iter().zip(lit.iter().zip(&sun?)) {
        let sky = *lb - *sb;
        let halves = lh
            .zip(*sh)
            .map(|(a, b)| HorizonLight(std::array::from_fn(|k| a.0[k] - b.0[k])));
        let Some(r) = reference_groups(full, p)? else {
            continue;
        };
        let c = match coarser {
            Some(c) => reference_groups(c, p)?,
            None => None,
        };
        tally.add(groups(&sky, halves.as_ref()), c, r);
    }
    Ok(())
}

/// The report's line for `g` (none where no point was tallied).
pub(super) fn line(g: &BinGroups) -> String {
    if g.points == 0 {
        return String::new();
    }
    let row = |v: &[f64; 4]| {
        GROUPS
            .iter()
            .zip(v)
            .map(|(n, r)| format!("{n} {r:.3}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut s = format!(
        "  the finest depth's sky by the way it travels, over the 1 m sweep's at its {} volume points (sums over the path): the hierarchy {}",
        g.points,
        row(&g.hierarchy)
    );
    if let Some(c) = &g.coarser_sweep {
        s.push_str(&format!(
            "; one sweep at the next coarser depth's cell {}",
            row(c)
        ));
    }
    s.push('\n');
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightgrid_core::dirs::NUM_DIRS;

    /// Known answers: a light of 1 in every bin holds 9 down, 4 and 4 across the
    /// horizon (even halves where none are given), 9 up; given halves move light
    /// between the horizontal groups and nothing else.
    #[test]
    fn groups_split_the_bins_by_the_way_they_travel() {
        let b = BinLight([Vec3::ONE; NUM_DIRS]);
        let g = groups(&b, None);
        for (got, want) in g.iter().zip([9.0, 4.0, 4.0, 9.0]) {
            assert!((got - want).abs() < 1e-5, "{g:?}");
        }
        let down = HorizonLight([Vec3::splat(0.75); HORIZONTAL_BINS]);
        let g = groups(&b, Some(&down));
        for (got, want) in g.iter().zip([9.0, 6.0, 2.0, 9.0]) {
            assert!((got - want).abs() < 1e-5, "{g:?}");
        }
    }

    /// The ratios: 1 where the sums agree, the sums' ratio where they don't; the
    /// coarser sweep's only where one was tallied.
    #[test]
    fn ratios_are_the_sums_over_the_reference() {
        let mut t = BinTally::default();
        t.add([1.0, 2.0, 3.0, 4.0], None, [1.0, 2.0, 3.0, 4.0]);
        t.add([1.0, 0.0, 3.0, 4.0], None, [1.0, 2.0, 3.0, 4.0]);
        let g = t.groups();
        assert_eq!(g.points, 2);
        assert_eq!(g.hierarchy, [1.0, 0.5, 1.0, 1.0]);
        assert!(g.coarser_sweep.is_none());
        t.add([1.0; 4], Some([2.0; 4]), [1.0; 4]);
        let g = t.groups();
        // Over the one point it was read at.
        assert_eq!(g.coarser_sweep.map(|c| c[0]), Some(2.0));
        assert!(line(&g).contains("horizontal going up"));
        assert!(line(&BinGroups::default()).is_empty());
    }
}
