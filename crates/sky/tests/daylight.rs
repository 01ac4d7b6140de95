//! The daylight sky (`lightgrid_sky::Daylight`) against measured clear skies and the
//! shape Preetham's model must have.

use lightgrid_core::glam::Vec3;
use lightgrid_sky::{Daylight, SkySpec, Sun, ies_sky_illuminance, ies_sun_illuminance};

fn toward(elevation_deg: f32, azimuth_deg: f32) -> Vec3 {
    Sun::at(
        elevation_deg.to_radians(),
        azimuth_deg.to_radians(),
        Vec3::ONE,
    )
    .direction
}

/// On a horizontal surface the sky gives the IES clear-sky illuminance at every sun
/// elevation and turbidity (the map to 0.1 %; the bins as a uniform sky's are read),
/// in lux for a sky in cd/m², and the sun the IES direct illuminance: at 40° the sky
/// is 13.2 klux and the sun 59.2 klux on the ground.
#[test]
fn the_sky_and_the_sun_light_the_ground_as_measured_clear_skies_do() {
    let uniform = lightgrid_sky::uniform_sky(Vec3::ONE)
        .unwrap()
        .top
        .irradiance(Vec3::Y);
    let uniform_loss = uniform.x / std::f32::consts::PI;
    assert!((0.9..1.0).contains(&uniform_loss), "{uniform_loss}");
    for elevation in [5.0f32, 20.0, 40.0, 60.0, 85.0] {
        for turbidity in [2.0, 3.0, 6.0] {
            let d = Daylight::new(turbidity, toward(elevation, 30.0)).unwrap();
            let want = ies_sky_illuminance(elevation.to_radians());
            let map = d.env_map(512, 256).unwrap();
            let got = map.horizontal_illuminance();
            assert!(
                (got - want).abs() <= 1e-3 * want,
                "{elevation}° T {turbidity}: {got} vs {want}"
            );
            let bins = map.bins().top.irradiance(Vec3::Y);
            let y = lightgrid_core::light::luminance(bins);
            // The 26 bins read a sky's upward illuminance low (issue 44: the horizontal
            // bins' upper halves are read as spread across the horizon; a uniform sky
            // loses 5.6 %): the daylight sky loses what a uniform one does, within 1.5 %.
            assert!(
                (y / want - uniform_loss).abs() <= 0.015,
                "{elevation}° T {turbidity}: bins {y} vs {want} (a uniform sky: x{uniform_loss})"
            );
            assert_eq!(
                d.sun_illuminance(),
                ies_sun_illuminance(elevation.to_radians())
            );
        }
    }
    let (sky, sun) = (
        ies_sky_illuminance(40f32.to_radians()),
        ies_sun_illuminance(40f32.to_radians()),
    );
    assert!((sky - 13.23e3).abs() < 50.0, "{sky}");
    assert!(
        (sun * 40f32.to_radians().sin() - 59.2e3).abs() < 200.0,
        "{sun}"
    );
}

/// Preetham's distribution: brightest around the sun, darkest about 90° from it, brighter
/// toward the horizon than at the zenith away from the sun; blue overhead on a clear day,
/// whiter with haze; nothing below the horizon; the same luminance either side of the
/// sun's vertical plane.
#[test]
fn the_sky_has_preethams_shape_and_colour() {
    let sun = toward(30.0, 0.0);
    let d = Daylight::new(3.0, sun).unwrap();
    let map = d.env_map(360, 180).unwrap();
    let at = |elevation: f32, azimuth: f32| {
        let dir = toward(elevation, azimuth);
        // The texel holding `dir` (the map's layout: see the crate docs).
        let (w, h) = (map.width() as f32, map.height() as f32);
        let phi = dir.x.atan2(-dir.z);
        let theta = dir.y.clamp(-1.0, 1.0).acos();
        let x = (((phi + std::f32::consts::PI) / std::f32::consts::TAU * w) as u32)
            .min(map.width() - 1);
        let y = ((theta / std::f32::consts::PI * h) as u32).min(map.height() - 1);
        map.texels()[(y * map.width() + x) as usize]
    };
    let y = |c: Vec3| lightgrid_core::light::luminance(c);
    let near_sun = y(at(35.0, 5.0));
    let zenith = y(at(89.5, 0.0));
    let side = y(at(30.0, 90.0));
    let opposite_low = y(at(5.0, 180.0));
    let opposite_high = y(at(60.0, 180.0));
    assert!(near_sun > 3.0 * zenith, "{near_sun} {zenith}");
    assert!(
        side < near_sun && opposite_high < zenith * 1.5,
        "{side} {opposite_high}"
    );
    assert!(
        opposite_low > opposite_high,
        "{opposite_low} {opposite_high}"
    );
    assert!((y(at(30.0, 90.0)) - y(at(30.0, -90.0))).abs() < 0.02 * side);
    let blue = at(89.5, 0.0);
    assert!(blue.z > blue.x, "{blue}");
    let hazy = Daylight::new(8.0, sun).unwrap().env_map(360, 180).unwrap();
    let h = hazy.texels()[(hazy.width() / 2) as usize];
    let c = map.texels()[(map.width() / 2) as usize];
    assert!(h.z / h.x < c.z / c.x, "haze whitens the zenith: {h} vs {c}");
    assert!(map.texels()[map.texels().len() - 1] == Vec3::ZERO);
}

#[test]
fn below_the_horizon_the_sky_is_dark_and_bad_turbidity_is_named() {
    let d = SkySpec::Daylight(3.0).bins(toward(-5.0, 0.0)).unwrap();
    assert_eq!(d.top.total(), Vec3::ZERO);
    let e = Daylight::new(0.5, Vec3::Y).unwrap_err().to_string();
    assert!(e.contains("turbidity"), "{e}");
    let e = Daylight::new(f32::NAN, Vec3::Y).unwrap_err().to_string();
    assert!(e.contains("turbidity"), "{e}");
    let e = Daylight::new(3.0, Vec3::ZERO).unwrap_err().to_string();
    assert!(e.contains("sun_direction"), "{e}");
    assert!(SkySpec::Daylight(3.0).follows_sun());
}
