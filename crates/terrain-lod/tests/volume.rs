//! The hierarchy's light-volume sampler against its bins (`Hierarchy::volume_sampler`,
//! `crate::volume`).

use lightgrid_core::glam::Vec3;
use lightgrid_core::{LightField, VolumeSample};
use lightgrid_terrain_lod::NodeKey;

mod block;

/// Where a lookup's eight corners are valid the volume reads what the bins give; on
/// the ground's surface it reads the light just above it (within 2 %), where the
/// bins read about half of it.
#[test]
fn the_volume_reads_the_bins_and_fills_points_inside_geometry() {
    let h = block::hierarchy(0.0);
    assert!(h.ready_nodes().iter().any(|k: &NodeKey| k.depth == 2));
    let read = h.volume_sampler().unwrap();
    for i in 0..200 {
        // Well above the ground's cells and away from the block: valid corners.
        let p = Vec3::new(
            2.0 + 0.3 * i as f32,
            3.5 + 0.05 * i as f32,
            50.0 - 0.2 * i as f32,
        );
        let (a, b) = (read(p).unwrap(), VolumeSample::read(&h, p).unwrap());
        assert!(
            (a.average - b.average).abs().max_element() <= 1e-5 * b.average.max_element(),
            "{p}: {a:?} {b:?}"
        );
        assert!(
            (a.dominant - b.dominant).length() <= 1e-4,
            "{p}: {a:?} {b:?}"
        );
    }
    for x in [5.0, 13.0, 41.0] {
        // The ground's surface lies between the last grid point inside and the first
        // above.
        let g = h.grid_at(Vec3::new(x, 0.0, 40.0));
        let d = g.desc();
        // (The last point below height 0: its cell is ground.)
        let below = ((0.0 - d.origin().y) / d.h()).ceil() - 1.0;
        let y_in = d.origin().y + below * d.h();
        let y_up = y_in + d.h();
        assert!(y_in < 0.0 && y_up >= 0.0, "{y_in} {y_up}");
        let surface = Vec3::new(x, 0.5 * (y_in + y_up), 40.0);
        let above = read(Vec3::new(x, y_up, 40.0)).unwrap().average;
        let got = read(surface).unwrap().average;
        let bins = VolumeSample::read(&h, surface).unwrap().average;
        assert!(
            (got - above).abs().max_element() <= 0.02 * above.max_element(),
            "{got} vs {above}"
        );
        assert!(
            bins.max_element() < 0.8 * above.max_element(),
            "the bins read {bins}, above {above}"
        );
    }
}
