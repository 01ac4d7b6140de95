//! naga checks that need no GPU: a shader parses and validates, and a Rust struct has
//! the layout of its WGSL declaration.

/// Parses and validates `src` (named `name` in errors) with every validation flag and
/// capability, and refuses what is not portable ([`signed_remainders`]); the module for
/// further checks.
pub fn validate(name: &str, src: &str) -> Result<naga::Module, String> {
    let module = naga::front::wgsl::parse_str(src)
        .map_err(|e| format!("{name}: {}", e.emit_to_string(src)))?;
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .map_err(|e| format!("{name}: {e:?}"))?;
    let signed = signed_remainders(&module, &info);
    if !signed.is_empty() {
        return Err(format!(
            "{name}: `%` on signed integers in {}: undefined on OpenGL for negative \
             operands (naga writes it to GLSL as it is); use the prelude's wrap_index or \
             unsigned operands",
            signed.join(", ")
        ));
    }
    let copied = indexed_array_values(&module, &info);
    if !copied.is_empty() {
        return Err(format!(
            "{name}: an array value (a `const` or `let` array) indexed at run time in {}: \
             naga's SPIR-V writer copies the whole array into a variable at every such \
             read; index a `var` holding it instead",
            copied.join(", ")
        ));
    }
    Ok(module)
}

/// The functions (by name) of `module` that index an array *value* at run time (a
/// `const` array, or one bound by `let`), not a variable or a buffer. naga's SPIR-V
/// writer spills such a value into a fresh function variable at every read: the
/// sampling kernel's loop over the 26 directions, reading the prelude's `DIR_UNIT` at
/// its index, copied 26 × 26 vectors a point, and the light volume's sampling on
/// lavapipe took 10.7 s with it, 7.3 s without (`docs/measurements.md`).
pub fn indexed_array_values(module: &naga::Module, info: &naga::valid::ModuleInfo) -> Vec<String> {
    functions_with(module, info, |e, fi| {
        matches!(*e, naga::Expression::Access { base, .. }
            if matches!(fi[base].ty.inner_with(&module.types), naga::TypeInner::Array { .. }))
    })
}

/// The names of `module`'s functions and entry points holding an expression for which
/// `hit` (given the function's validation info) is true.
fn functions_with(
    module: &naga::Module,
    info: &naga::valid::ModuleInfo,
    hit: impl Fn(&naga::Expression, &naga::valid::FunctionInfo) -> bool,
) -> Vec<String> {
    let scan = |f: &naga::Function, fi: &naga::valid::FunctionInfo| {
        f.expressions.iter().any(|(_, e)| hit(e, fi))
    };
    let functions = module
        .functions
        .iter()
        .filter(|&(h, f)| scan(f, &info[h]))
        .map(|(_, f)| f.name.clone().unwrap_or_default());
    let entries = module
        .entry_points
        .iter()
        .enumerate()
        .filter(|&(i, ep)| scan(&ep.function, info.get_entry_point(i)))
        .map(|(_, ep)| ep.name.clone());
    functions.chain(entries).collect()
}

/// The functions (by name) of `module` that take a remainder (`%`) of signed integers
/// at run time. WGSL defines it for negative operands; GLSL does not, and naga's GLSL
/// writer emits it unchanged, so such a shader gives other results on the OpenGL
/// backend (the GPU sweeper's periodic sides did: wrong cells on llvmpipe through GL).
pub fn signed_remainders(module: &naga::Module, info: &naga::valid::ModuleInfo) -> Vec<String> {
    functions_with(module, info, |e, fi| {
        matches!(*e, naga::Expression::Binary { op: naga::BinaryOperator::Modulo, left, .. }
            if fi[left].ty.inner_with(&module.types).scalar_kind()
                == Some(naga::ScalarKind::Sint))
    })
}

/// Checks that the WGSL struct `name` in `src` has exactly the fields `offsets` (name and
/// byte offset, in order, as [`gpu_struct!`](crate::gpu_struct)'s `offsets()` gives them)
/// and the size `size`, in naga's layout of the parsed shader. `Err` says what differs.
pub fn layout(src: &str, name: &str, offsets: &[(&str, usize)], size: usize) -> Result<(), String> {
    let module = naga::front::wgsl::parse_str(src).map_err(|e| format!("parse: {e}"))?;
    layout_in(&module, name, offsets, size)
}

/// [`layout`] on an already parsed module.
pub fn layout_in(
    module: &naga::Module,
    name: &str,
    offsets: &[(&str, usize)],
    size: usize,
) -> Result<(), String> {
    let ty = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .ok_or_else(|| format!("no struct {name}"))?
        .1;
    let naga::TypeInner::Struct { members, span } = &ty.inner else {
        return Err(format!("{name} is not a struct"));
    };
    let wgsl: Vec<(&str, usize)> = members
        .iter()
        .map(|m| (m.name.as_deref().unwrap_or(""), m.offset as usize))
        .collect();
    if wgsl != offsets {
        return Err(format!(
            "{name}: WGSL fields {wgsl:?}, Rust fields {offsets:?}"
        ));
    }
    if *span as usize != size {
        return Err(format!("{name}: WGSL size {span}, Rust size {size}"));
    }
    Ok(())
}

#[cfg(test)]
#[allow(unreachable_pub)] // the macro declares public items; here in a private test module
mod tests {
    crate::gpu_struct! {
        /// A test block.
        pub struct Probe {
            /// A vector.
            pub a: [f32; 4] => "vec4<f32>",
            /// A scalar.
            pub b: u32 => "u32",
            /// Padding.
            pub _pad0: u32 => "u32",
            /// Padding.
            pub _pad1: [u32; 2] => "vec2<u32>",
        }
    }

    /// A signed `%` is refused by name (GLSL leaves it undefined for negative
    /// operands); the prelude's `wrap_index` wraps like WGSL's `(i % n + n) % n`.
    #[test]
    fn signed_remainders_are_refused() {
        let prelude = crate::wgsl::prelude();
        let bad =
            format!("{prelude}\nfn wrap(i: i32, n: i32) -> i32 {{ return (i % n + n) % n; }}");
        let e = super::validate("bad", &bad).unwrap_err();
        assert!(e.contains("wrap") && e.contains("signed"), "{e}");
        let vector =
            format!("{prelude}\nfn v(i: vec2<i32>) -> vec2<i32> {{ return i % vec2<i32>(3); }}");
        assert!(super::validate("vector", &vector).is_err());
        for ok in [
            "fn u(i: u32, n: u32) -> u32 { return i % n; }",
            "fn f(x: f32) -> f32 { return x % 2.0; }",
            "const C: i32 = -7 % 3;",
        ] {
            super::validate("ok", &format!("{prelude}\n{ok}")).unwrap();
        }
    }

    /// A `const` or `let` array indexed at run time is refused by name (naga's SPIR-V
    /// copies the array at every read); a `var` holding it, a constant index and a
    /// buffer are not.
    #[test]
    fn array_values_indexed_at_run_time_are_refused() {
        let prelude = crate::wgsl::prelude();
        for bad in [
            "fn unit(d: u32) -> vec3<f32> { return DIR_UNIT[d]; }",
            "fn pick(i: u32, a: f32) -> f32 { let v = array<f32, 2>(a, 1.0); return v[i]; }",
        ] {
            let e = super::validate("bad", &format!("{prelude}\n{bad}")).unwrap_err();
            assert!(
                e.contains("run time") && (e.contains("unit") || e.contains("pick")),
                "{e}"
            );
        }
        for ok in [
            "fn unit(d: u32) -> vec3<f32> { var u = DIR_UNIT; return u[d]; }",
            "fn first() -> vec3<f32> { return DIR_UNIT[0]; }",
            "fn pick(a: f32) -> f32 { let v = array<f32, 2>(a, 1.0); return v[1]; }",
            "var<private> table: array<f32, 4>;\nfn t(i: u32) -> f32 { return table[i]; }",
        ] {
            super::validate("ok", &format!("{prelude}\n{ok}")).unwrap();
        }
    }

    #[test]
    fn generated_structs_match_naga_and_mismatches_are_named() {
        assert!(
            super::validate("bad", "fn f( {")
                .unwrap_err()
                .starts_with("bad")
        );
        let src = format!(
            "{}\n@group(0) @binding(0) var<uniform> p: Probe;",
            Probe::wgsl()
        );
        super::layout(
            &src,
            "Probe",
            &Probe::offsets(),
            std::mem::size_of::<Probe>(),
        )
        .unwrap();
        let e = super::layout(&src, "Probe", &[("a", 0), ("b", 4)], 32).unwrap_err();
        assert!(e.contains("Rust fields"), "{e}");
        let e = super::layout(&src, "Probe", &Probe::offsets(), 16).unwrap_err();
        assert!(e.contains("size"), "{e}");
        assert!(
            super::layout(&src, "Missing", &[], 0)
                .unwrap_err()
                .contains("no struct")
        );
    }
}
