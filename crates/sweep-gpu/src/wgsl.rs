//! WGSL sources. Constants shared with Rust are generated, never copied by hand:
//! `lightgrid_gpu::wgsl::prelude` (the direction tables of `lightgrid-core`) is prepended
//! to every shader, then the sweep's tables from `sweep-cpu` ([`sweep_tables`]) and the
//! per-level block `LevelParams` (declared once with `lightgrid_gpu::gpu_struct!`).

use std::fmt::Write;

/// One table of the sweep: its WGSL accessor's name, the type it returns, and its
/// values, `components` floats an entry (integers stored as exact floats).
struct Table {
    name: &'static str,
    ty: &'static str,
    components: usize,
    values: Vec<f32>,
}

/// The sweep's channel tables, generated from `lightgrid_sweep_cpu::sweep::channels` (the
/// specification): steps, flux factors, bins of both passes, stencils and their path
/// exponents, the source rule's weights and split table, the height profile's slot
/// geometry, and the directions' unit vectors and solid angles.
fn tables() -> Vec<Table> {
    use lightgrid_sweep_cpu::sweep::{MAX_EXPONENTS, channels, path_exponents};
    let (down, up) = (channels(false), channels(true));
    let int = |v: i64| v as f32;
    let e = path_exponents();
    let w = lightgrid_sweep_cpu::medium::weights(false);
    let t = |name, ty, components, values: Vec<f32>| Table {
        name,
        ty,
        components,
        values,
    };
    vec![
        t(
            "ch_step",
            "vec2<i32>",
            2,
            down.iter()
                .flat_map(|c| [int(c.step.x as i64), int(c.step.z as i64)])
                .collect(),
        ),
        t("ch_mu", "f32", 1, down.iter().map(|c| c.mu).collect()),
        t("ch_share", "f32", 1, down.iter().map(|c| c.share).collect()),
        t(
            "ch_bin_down",
            "u32",
            1,
            down.iter().map(|c| int(c.bin as i64)).collect(),
        ),
        t(
            "ch_bin_up",
            "u32",
            1,
            up.iter().map(|c| int(c.bin as i64)).collect(),
        ),
        t(
            "ch_first_slot",
            "u32",
            1,
            down.iter().map(|c| int(c.first_slot as i64)).collect(),
        ),
        t(
            "ch_nstencil",
            "u32",
            1,
            down.iter().map(|c| int(c.stencil.len() as i64)).collect(),
        ),
        t(
            "stencil_d",
            "vec2<i32>",
            2,
            down.iter()
                .flat_map(|c| c.stencil.iter())
                .flat_map(|&(dx, dz, _)| [int(dx as i64), int(dz as i64)])
                .collect(),
        ),
        t(
            "stencil_e",
            "f32",
            1,
            down.iter()
                .flat_map(|c| c.pow.iter().map(|&k| e[k] as f32))
                .collect(),
        ),
        // The source rule (`lightgrid_sweep_cpu::medium`): per path exponent its value and
        // the pass's weight (the same in both passes), the channels' `ω_b σ_c`, the split
        // table.
        t(
            "path_e",
            "f32",
            1,
            (0..MAX_EXPONENTS)
                .map(|k| e.get(k).copied().unwrap_or(0.0) as f32)
                .collect(),
        ),
        t("src_w", "f32", 1, w.w.to_vec()),
        t("src_omega", "f32", 1, w.omega.to_vec()),
        t(
            "split_table",
            "f32",
            1,
            lightgrid_sweep_cpu::medium::split_table().to_vec(),
        ),
        // The quadratic source in height (`lightgrid_sweep_cpu::profile`): per pass and
        // slot `(μ_c ω_b σ_c, e, ū_1, ū_2)`.
        t(
            "prof_geo",
            "vec4<f32>",
            4,
            [false, true]
                .iter()
                .flat_map(|&up| lightgrid_sweep_cpu::profile::slot_geometry(up).iter())
                .flat_map(|&(w, e, u)| [w, e, u[0], u[1]])
                .collect(),
        ),
        t(
            "dir_unit",
            "vec3<f32>",
            3,
            lightgrid_core::dirs::units()
                .iter()
                .flat_map(|v| v.to_array())
                .collect(),
        ),
        t(
            "solid_angle",
            "f32",
            1,
            lightgrid_core::dirs::solid_angles().to_vec(),
        ),
    ]
}

/// Floats of the profile's tables at the head of [`table_floats`] (known without
/// building them: [`sweep_tables`] only needs where its accessors start).
const PROFILE_FLOATS: usize =
    lightgrid_sweep_cpu::profile::TABLE * lightgrid_sweep_cpu::profile::NODE_FLOATS;

/// The buffer the sweep's kernels read their tables from (`tables` in WGSL): the
/// profile's tables (`lightgrid_sweep_cpu::profile::table_floats`) first, then every
/// table of [`sweep_tables`]' accessors at the offsets those name. Uploaded once.
pub fn table_floats() -> Vec<f32> {
    let mut v = lightgrid_sweep_cpu::profile::table_floats();
    debug_assert_eq!(v.len(), PROFILE_FLOATS);
    for t in tables() {
        v.extend(t.values);
    }
    v
}

/// The sweep's scalar constants, and an accessor per table of [`table_floats`]
/// (`ch_mu(c)`, `stencil_d(k)`, ...) reading the `tables` buffer, declared with its
/// length (`TABLE_FLOATS`: bounds checks against a constant, cheaper on OpenGL than
/// against a runtime-sized array's length). Tables, not WGSL
/// `const` arrays: naga's SPIR-V writer stores a whole constant array into a function
/// variable at every access with a runtime index (its `spill_to_internal_variable`),
/// which made every sweep on lavapipe 4 times slower; a `var<private>` array instead is
/// written out per invocation on OpenGL (twice as slow there).
pub fn sweep_tables() -> String {
    use lightgrid_sweep_cpu::sweep::{MAX_EXPONENTS, SLOTS};
    let mut s = String::new();
    let _ = writeln!(
        s,
        "const FOUR_PI: f32 = {:?};",
        4.0f32 * std::f32::consts::PI
    );
    let w = lightgrid_sweep_cpu::medium::weights(false);
    let _ = writeln!(s, "const SRC_O: f32 = {:?};", w.o);
    let _ = writeln!(
        s,
        "const PROFILE_MAX_PASS: f32 = {:?};",
        lightgrid_sweep_cpu::medium::PROFILE_MAX_PASS
    );
    let _ = writeln!(
        s,
        "const SPLIT_TAU_MAX: f32 = {:?};",
        lightgrid_sweep_cpu::medium::SPLIT_TAU_MAX
    );
    let _ = writeln!(
        s,
        "const SPLIT_N: u32 = {}u;\nconst MAX_E: u32 = {MAX_EXPONENTS}u;",
        lightgrid_sweep_cpu::medium::SPLIT_TABLE,
    );
    // The quadratic source in height (`lightgrid_sweep_cpu::profile`): its table's layout.
    let _ = writeln!(
        s,
        "const PROF_N: u32 = {}u;\nconst PROF_TAU_MAX: f32 = {:?};\nconst PROF_NODE: u32 = {}u;\nconst SLOTS: u32 = {SLOTS}u;",
        lightgrid_sweep_cpu::profile::TABLE,
        lightgrid_sweep_cpu::profile::TAU_MAX as f32,
        lightgrid_sweep_cpu::profile::NODE_FLOATS
    );
    let tables = tables();
    let floats = PROFILE_FLOATS + tables.iter().map(|t| t.values.len()).sum::<usize>();
    let _ = writeln!(s, "const TABLE_FLOATS: u32 = {floats}u;");
    let mut at = PROFILE_FLOATS;
    for t in tables {
        let read = |k: usize| format!("tables[o + {k}u]");
        let body = match t.ty {
            "f32" => read(0),
            "u32" => format!("u32({})", read(0)),
            "vec2<i32>" => format!("vec2<i32>(i32({}), i32({}))", read(0), read(1)),
            "vec3<f32>" => format!("vec3<f32>({}, {}, {})", read(0), read(1), read(2)),
            "vec4<f32>" => format!(
                "vec4<f32>({}, {}, {}, {})",
                read(0),
                read(1),
                read(2),
                read(3)
            ),
            other => unreachable!("table type {other}"),
        };
        let _ = writeln!(
            s,
            "fn {}(i: u32) -> {} {{\n    let o = {at}u + {}u * i;\n    return {body};\n}}",
            t.name, t.ty, t.components
        );
        at += t.values.len();
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The accessors read the tables where [`table_floats`] put them: one after the
    /// other from the end of the profile's tables to the end of the buffer, each with
    /// its table's entry size, and each table a whole number of entries.
    #[test]
    fn accessors_tile_the_table_buffer() {
        let wgsl = sweep_tables();
        let mut at = lightgrid_sweep_cpu::profile::table_floats().len();
        assert_eq!(at, PROFILE_FLOATS);
        for t in tables() {
            assert_eq!(t.values.len() % t.components, 0, "{}", t.name);
            let want = format!(
                "fn {}(i: u32) -> {} {{\n    let o = {at}u + {}u * i;",
                t.name, t.ty, t.components
            );
            assert!(wgsl.contains(&want), "{want}");
            at += t.values.len();
        }
        assert_eq!(at, table_floats().len());
        let declared = format!("const TABLE_FLOATS: u32 = {at}u;");
        assert!(wgsl.contains(&declared), "{declared}");
        // Integers are stored exactly: the channels' steps read back as they are.
        let steps = &tables()[0];
        let want: Vec<f32> = lightgrid_sweep_cpu::sweep::channels(false)
            .iter()
            .flat_map(|c| [c.step.x, c.step.z])
            .map(|v| v as f32)
            .collect();
        assert_eq!((steps.name, &steps.values), ("ch_step", &want));
    }
}
