//! WGSL sources. Constants shared with Rust are generated, never copied by hand:
//! `lightgrid_gpu::wgsl::prelude` (the direction tables of `lightgrid-core`) is prepended
//! to every shader, then the sweep's tables from `sweep-cpu` ([`sweep_tables`]) and the
//! per-level block `LevelParams` (declared once with `lightgrid_gpu::gpu_struct!`).

use std::fmt::Write;

/// The sweep's channel tables, generated from `lightgrid_sweep_cpu::sweep::channels` (the
/// specification): steps, flux factors, bins of both passes, stencils and their path
/// exponents, and the opaque cells' surface weights.
pub fn sweep_tables() -> String {
    use lightgrid_sweep_cpu::sweep::{CHANNELS, MAX_EXPONENTS, SLOTS, channels, path_exponents};
    let (down, up) = (channels(false), channels(true));
    let mut s = String::new();
    let list = |v: Vec<String>| v.join(", ");
    let _ = writeln!(
        s,
        "const FOUR_PI: f32 = {:?};",
        4.0f32 * std::f32::consts::PI
    );
    let _ = writeln!(
        s,
        "const CH_STEP = array<vec2<i32>, {CHANNELS}>({});",
        list(
            down.iter()
                .map(|c| format!("vec2<i32>({}, {})", c.step.x, c.step.z))
                .collect()
        )
    );
    let _ = writeln!(
        s,
        "const CH_MU = array<f32, {CHANNELS}>({});",
        list(down.iter().map(|c| format!("{:?}", c.mu)).collect())
    );
    let _ = writeln!(
        s,
        "const CH_SHARE = array<f32, {CHANNELS}>({});",
        list(down.iter().map(|c| format!("{:?}", c.share)).collect())
    );
    let _ = writeln!(
        s,
        "const CH_BIN_DOWN = array<u32, {CHANNELS}>({});",
        list(down.iter().map(|c| format!("{}u", c.bin)).collect())
    );
    let _ = writeln!(
        s,
        "const CH_BIN_UP = array<u32, {CHANNELS}>({});",
        list(up.iter().map(|c| format!("{}u", c.bin)).collect())
    );
    let _ = writeln!(
        s,
        "const CH_FIRST_SLOT = array<u32, {CHANNELS}>({});",
        list(down.iter().map(|c| format!("{}u", c.first_slot)).collect())
    );
    let _ = writeln!(
        s,
        "const CH_NSTENCIL = array<u32, {CHANNELS}>({});",
        list(
            down.iter()
                .map(|c| format!("{}u", c.stencil.len()))
                .collect()
        )
    );
    let e = path_exponents();
    let _ = writeln!(
        s,
        "const STENCIL_D = array<vec2<i32>, {SLOTS}>({});",
        list(
            down.iter()
                .flat_map(|c| c
                    .stencil
                    .iter()
                    .map(|&(dx, dz, _)| format!("vec2<i32>({dx}, {dz})")))
                .collect()
        )
    );
    let _ = writeln!(
        s,
        "const STENCIL_E = array<f32, {SLOTS}>({});",
        list(
            down.iter()
                .flat_map(|c| c.pow.iter().map(|&k| format!("{:?}", e[k])))
                .collect()
        )
    );
    // The source rule (`lightgrid_sweep_cpu::medium`): per path exponent its value and the pass's
    // weight (the same in both passes), the channels' `ω_b σ_c`, `O / τ`, the split
    // table.
    let w = lightgrid_sweep_cpu::medium::weights(false);
    let _ = writeln!(
        s,
        "const PATH_E = array<f32, {MAX_EXPONENTS}>({});",
        list(
            (0..MAX_EXPONENTS)
                .map(|k| format!("{:?}", e.get(k).copied().unwrap_or(0.0)))
                .collect()
        )
    );
    let _ = writeln!(
        s,
        "const SRC_W = array<f32, {MAX_EXPONENTS}>({});",
        list(w.w.iter().map(|v| format!("{v:?}")).collect())
    );
    let _ = writeln!(
        s,
        "const SRC_OMEGA = array<f32, {CHANNELS}>({});",
        list(w.omega.iter().map(|v| format!("{v:?}")).collect())
    );
    let _ = writeln!(s, "const SRC_O: f32 = {:?};", w.o);
    let _ = writeln!(
        s,
        "const SPLIT_TAU_MAX: f32 = {:?};",
        lightgrid_sweep_cpu::medium::SPLIT_TAU_MAX
    );
    let _ = writeln!(
        s,
        "const SPLIT_N: u32 = {}u;\nconst MAX_E: u32 = {MAX_EXPONENTS}u;\nconst SPLIT = array<f32, {}>({});",
        lightgrid_sweep_cpu::medium::SPLIT_TABLE,
        lightgrid_sweep_cpu::medium::SPLIT_TABLE,
        list(
            lightgrid_sweep_cpu::medium::split_table()
                .iter()
                .map(|v| format!("{v:?}"))
                .collect()
        )
    );
    // The quadratic source in height (`lightgrid_sweep_cpu::profile`): its table's layout, and
    // per pass and slot `(μ_c ω_b σ_c, e, ū_1, ū_2)`.
    let _ = writeln!(
        s,
        "const PROF_N: u32 = {}u;\nconst PROF_TAU_MAX: f32 = {:?};\nconst PROF_NODE: u32 = {}u;\nconst SLOTS: u32 = {SLOTS}u;",
        lightgrid_sweep_cpu::profile::TABLE,
        lightgrid_sweep_cpu::profile::TAU_MAX as f32,
        lightgrid_sweep_cpu::profile::NODE_FLOATS
    );
    let _ = writeln!(
        s,
        "const PROF_GEO = array<vec4<f32>, {}>({});",
        2 * SLOTS,
        list(
            [false, true]
                .iter()
                .flat_map(|&up| lightgrid_sweep_cpu::profile::slot_geometry(up).iter())
                .map(|(w, e, u)| format!("vec4<f32>({w:?}, {e:?}, {:?}, {:?})", u[0], u[1]))
                .collect()
        )
    );
    s
}

/// Where the `free` half of [`surface_weight_table`] starts.
pub const SURFACE_FREE_OFFSET: usize = 64 * 2 * lightgrid_core::NUM_DIRS;

/// The opaque cells' surface weights (`lightgrid_sweep_cpu::sweep::surface_weights`) for all 64
/// exposure masks and both passes: `w` at `(mask * 2 + up) * 26 + bin`, then `free` at
/// `SURFACE_FREE_OFFSET` plus the same index, padded to 16-byte rows:
/// the contents of phase 2's uniform buffer (a uniform, not a constant: a dynamically
/// indexed constant array this size makes shader compilers build it in private memory
/// per invocation).
pub fn surface_weight_table() -> Vec<f32> {
    let mut v: Vec<f32> = (0..64u8)
        .flat_map(|m| lightgrid_sweep_cpu::sweep::surface_weights(m).w.concat())
        .collect();
    debug_assert_eq!(v.len(), SURFACE_FREE_OFFSET);
    v.extend((0..64u8).flat_map(|m| lightgrid_sweep_cpu::sweep::surface_weights(m).free.concat()));
    v.resize(v.len().div_ceil(4) * 4, 0.0);
    v
}

/// Floats of a point's level scratch: the removals of every stencil slot (RGB) and the
/// `T_after` of every channel.
pub const SCRATCH: usize =
    lightgrid_sweep_cpu::sweep::SLOTS * 3 + lightgrid_sweep_cpu::sweep::CHANNELS;

/// The part both sweep phases share: `struct LevelParams`, sizes, helpers.
fn sweep_common() -> String {
    let mut s = crate::sweep::LevelParams::wgsl();
    let _ = writeln!(s, "const SCRATCH: u32 = {SCRATCH}u;");
    let _ = writeln!(
        s,
        "const FIRST_HORIZONTAL: u32 = {}u;\nconst HORIZONTAL_BINS: u32 = {}u;",
        lightgrid_core::dirs::FIRST_HORIZONTAL,
        lightgrid_core::dirs::HORIZONTAL_BINS
    );
    let _ = writeln!(
        s,
        "const T_AFTER_OFFSET: u32 = {}u;",
        lightgrid_sweep_cpu::sweep::SLOTS * 3
    );
    let _ = writeln!(
        s,
        "const CH: u32 = {}u;",
        lightgrid_sweep_cpu::sweep::CHANNELS
    );
    s.push_str(include_str!("shaders/sweep_common.wgsl"));
    s
}

/// Phase 1 of a level (gather, transmit).
pub fn sweep_phase1() -> String {
    format!(
        "{}\n{}\n{}\n{}",
        lightgrid_gpu::wgsl::prelude(),
        sweep_tables(),
        sweep_common(),
        include_str!("shaders/sweep.wgsl")
    )
}

/// Phase 2 of a level (collect, absorb, emit).
pub fn sweep_phase2() -> String {
    let body = include_str!("shaders/sweep_phase2.wgsl")
        .replace(
            "LOCAL_ROUNDS_GEN",
            &format!("{}u", lightgrid_sweep_cpu::sweep::LOCAL_ROUNDS),
        )
        .replace(
            "SURFACE_ROWS_GEN",
            &format!("{}", surface_weight_table().len() / 4),
        )
        .replace(
            "SURFACE_FREE_OFFSET_GEN",
            &format!("{SURFACE_FREE_OFFSET}u"),
        );
    format!(
        "{}\n{}\n{}\n{}",
        lightgrid_gpu::wgsl::prelude(),
        sweep_tables(),
        sweep_common(),
        body
    )
}

/// The R11G11B10 packing functions.
pub const PACK: &str = include_str!("shaders/pack.wgsl");

/// The packing kernel, complete.
pub fn pack_kernel() -> String {
    format!(
        "{}\n{}\n{}",
        lightgrid_gpu::wgsl::prelude(),
        PACK,
        include_str!("shaders/pack_kernel.wgsl")
    )
}

/// The maximum kernel (largest channel, for the exposure).
pub fn max_kernel() -> String {
    include_str!("shaders/max_kernel.wgsl").to_string()
}

/// The sun transmittance march (`crate::sun`).
pub fn sun_kernel() -> String {
    format!(
        "{}\n{}\n{}",
        lightgrid_gpu::wgsl::prelude(),
        crate::sun::SunParams::wgsl(),
        include_str!("shaders/sun.wgsl")
    )
}

/// Every complete shader this crate compiles, by name (for validation).
pub fn all() -> Vec<(&'static str, String)> {
    vec![
        ("pack_kernel", pack_kernel()),
        ("max_kernel", max_kernel()),
        ("sweep_phase1", sweep_phase1()),
        ("sweep_phase2", sweep_phase2()),
        ("sun_kernel", sun_kernel()),
    ]
}
