//! Every file reader over a few thousand generated bad inputs (the CI share of
//! `cargo xtask fuzz`, which runs a million per reader): no panic may escape, no input
//! may be slow, and every reader must reject most mutated inputs and accept its seeds.

#[test]
fn every_reader_survives_generated_bad_inputs() {
    // Debug builds of the numeric crates are optimised (see the workspace profile), so a
    // few thousand inputs take seconds.
    for t in xtask::fuzz::targets() {
        let r = xtask::fuzz::run_target(&t, 3000, 42, None);
        println!("{}", r.line());
        assert_eq!(r.escaped_panics, 0, "{}: panics escaped the reader", t.name);
        assert_eq!(
            r.slow,
            0,
            "{}: inputs slower than {:?}",
            t.name,
            xtask::fuzz::SLOW
        );
        assert_eq!(r.accepted + r.rejected, r.inputs, "{}", t.name);
        assert!(
            r.rejected > 0,
            "{}: nothing was rejected: the mutations do nothing",
            t.name
        );
    }
}
