//! Every public constructor and entry point of the core over extreme values (0, 1,
//! `u32::MAX`, `f32::MAX`, subnormals, NaN, infinities, sizes whose products overflow):
//! a typed error or a finite result, never a panic or a NaN (issue 47).

use lightgrid_core::glam::{UVec3, Vec2, Vec3};
use lightgrid_core::{
    BinLight, Grid, GridDesc, GridFile, Heightmap, LightGrid, Material, MaterialGrid, NUM_DIRS,
};
use proptest::prelude::*;

/// The shared extreme values (`lightgrid_core::extremes`), any `f32`.
fn f() -> impl Strategy<Value = f32> {
    prop_oneof![
        proptest::sample::select(&lightgrid_core::extremes::F32[..]),
        any::<f32>(),
    ]
}

fn v3() -> impl Strategy<Value = Vec3> {
    (f(), f(), f()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

/// Sizes: the edges of `u32` and small ones (that allocate little).
fn size() -> impl Strategy<Value = u32> {
    prop_oneof![
        Just(0u32),
        Just(1),
        Just(2),
        Just(3),
        Just(1 << 16),
        Just(1 << 31),
        Just(u32::MAX),
        0u32..6,
    ]
}

fn bins() -> impl Strategy<Value = BinLight> {
    proptest::collection::vec(v3(), NUM_DIRS).prop_map(|v| BinLight(std::array::from_fn(|d| v[d])))
}

fn finite(v: Vec3) -> bool {
    v.is_finite()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// A descriptor is refused or describes finite positions; a grid over it is refused
    /// (memory, values) or holds what it was given.
    #[test]
    fn grid_descriptors_and_grids(origin in v3(), h in f(), dims in (size(), size(), size()), value in v3()) {
        lightgrid_core::limits::set_memory_limit(64 << 20);
        let Ok(d) = GridDesc::new(origin, h, UVec3::new(dims.0, dims.1, dims.2)) else {
            return Ok(());
        };
        let last = d.dims() - UVec3::ONE;
        prop_assert!(d.position(UVec3::ZERO).is_finite() && d.position(last).is_finite());
        if let Ok(g) = LightGrid::filled(d, BinLight::uniform(value)) {
            prop_assert!(g.data().iter().all(|b| b.is_valid()));
            let s = g.sample(origin);
            prop_assert!(s.map_or(true, |b| b.is_valid()));
        }
        let m = MaterialGrid::filled(d, Material { reflectance: value, pass: h });
        if let Ok(m) = m {
            prop_assert!(m.data().iter().all(|c| c.pass.is_finite()));
        }
        if let Ok(g) = Grid::filled(d, lightgrid_core::AverageLight(value)) {
            prop_assert!(g.level(dims.1).len() <= d.level_len());
        }
    }

    /// Every projection of any bins is finite (sums past `f32::MAX` saturate, NaN reads
    /// 0); the horizon split's parts are finite and its share in [0, 1].
    #[test]
    fn projections_of_any_bins_are_finite(b in bins(), n in v3()) {
        prop_assert!(finite(b.total()) && finite(b.average()));
        prop_assert!(finite(b.irradiance(n)));
        prop_assert!(b.dominant().is_finite());
        prop_assert!(b.sh2().0.iter().all(|c| c.is_finite()));
        prop_assert!(b.ambient_cube().0.iter().all(|c| c.is_finite()));
        for d in 0..NUM_DIRS {
            let s = b.horizon_share(d);
            prop_assert!(s.is_finite() && s.cmpge(Vec3::ZERO).all() && s.cmple(Vec3::ONE).all());
        }
        if b.is_valid() {
            let (down, up) = b.split_vertical_by_neighbours();
            prop_assert!(down.is_valid() && up.is_valid());
        }
    }

    /// A heightmap is refused or reads a finite height anywhere.
    #[test]
    fn heightmaps(origin in (f(), f()), spacing in f(), w in size(), d in size(), h in f(), x in f(), z in f()) {
        lightgrid_core::limits::set_memory_limit(64 << 20);
        let n = (w as u64 * d as u64).min(64) as usize;
        if let Ok(hm) = Heightmap::new(Vec2::new(origin.0, origin.1), spacing, w, d, vec![h; n]) {
            prop_assert!(hm.height_at(x, z).is_finite());
            let (lo, hi) = hm.range();
            prop_assert!(lo.is_finite() && hi.is_finite());
        }
    }

    /// A sun is refused or unit; trilinear weights are finite and sum to 1.
    #[test]
    fn suns_and_trilinear_weights(to_sun in v3(), irr in v3(), dims in (size(), size(), size()), g in v3()) {
        if let Ok(s) = lightgrid_core::light::check_sun(to_sun, irr) {
            prop_assert!((s.length() - 1.0).abs() < 1e-5);
        }
        match lightgrid_core::unit(to_sun) {
            Some(u) => {
                prop_assert!((u.length() - 1.0).abs() < 1e-5, "{u}");
                // Same direction: each component has the sign of the input's.
                prop_assert!((0..3).all(|a| u[a] == 0.0 || u[a].signum() == to_sun[a].signum()));
            }
            None => prop_assert!(!to_sun.is_finite() || to_sun == Vec3::ZERO),
        }
        let c = lightgrid_core::trilinear_corners(UVec3::new(dims.0, dims.1, dims.2), g);
        let sum: f32 = c.iter().map(|p| p.1).sum();
        prop_assert!(c.iter().all(|p| p.1.is_finite() && p.1 >= 0.0));
        prop_assert!(sum == 0.0 || (sum - 1.0).abs() < 1e-4, "{sum}");
    }

    /// Grid files of any bytes and any size limit: refused or whole.
    #[test]
    fn grid_files_of_any_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..256), limit in prop_oneof![Just(0u64), Just(1), Just(u64::MAX), any::<u64>()]) {
        lightgrid_core::limits::set_memory_limit(64 << 20);
        let _ = GridFile::from_bytes_limited(&bytes, limit);
    }
}

/// Found by `cargo xtask fuzz --target api`: light of opposite signs near `f32::MAX`
/// cancels to a tiny total, and the direction divided by it was infinite (then NaN).
#[test]
fn a_dominant_direction_of_cancelling_light_is_finite() {
    let mut b = BinLight::ZERO;
    b.0[2] = Vec3::new(3.57e-43, 1.7014118e38, 0.0);
    b.0[5] = Vec3::new(0.0, -1.7014118e38, 0.0);
    b.0[0] = Vec3::new(0.0, 0.0, 9.1835e-41);
    assert!(b.dominant().is_finite());
    let mut huge = BinLight::ZERO;
    huge.0[0] = Vec3::splat(f32::MAX);
    huge.0[1] = Vec3::splat(f32::MAX);
    let d = huge.dominant();
    assert!(d.is_finite() && d.length() > 0.5, "{d}");
}

/// A sun toward a direction of subnormal and tiny components (found by CI: the plain
/// normalisation gave a length of 0.98) is unit.
#[test]
fn a_sun_of_tiny_components_is_unit() {
    let to_sun = Vec3::new(1.1754944e-38, -0.0, 8.951674e-22);
    let s = lightgrid_core::light::check_sun(to_sun, Vec3::ONE).unwrap();
    assert!((s.length() - 1.0).abs() < 1e-6, "{s}");
    assert!(s.distance(Vec3::Z) < 1e-6, "{s}");
}
