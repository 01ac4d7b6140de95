//! Probe directions over extreme counts (issue 47): `fibonacci(i, 0)` divided by zero.

use proptest::prelude::*;

proptest! {
    #[test]
    fn fibonacci_directions_are_unit_for_any_count(
        i in prop_oneof![Just(0u32), Just(u32::MAX), any::<u32>()],
        n in prop_oneof![Just(0u32), Just(1), Just(u32::MAX), any::<u32>()],
    ) {
        let d = lightgrid_light_probes::fibonacci(i, n);
        prop_assert!(d.is_finite() && (d.length() - 1.0).abs() < 1e-4, "{d}");
    }
}
