//! The check that a node's Rust parameter struct and the WGSL struct its shader reads have one
//! layout: every WGSL member has a Rust field of the same name at the same offset and size,
//! the Rust fields tile the struct (an unlisted field leaves a hole), and the sizes agree. The
//! WGSL side comes from naga's reflection of the composed shader, not from the source text.

use crate::gpu::wgsl::{compose, Wgsl};
use crate::gpu::ShaderPrecision;

/// One Rust field: name, byte offset, byte size.
pub(crate) type Field = (&'static str, usize, usize);

/// A WGSL struct's span and its members (name, offset, size).
type WgslLayout = (usize, Vec<(String, usize, usize)>);

/// The layout of a `#[repr(C)]` Pod struct from its field list:
/// `rust_layout!(MarchUniform { tex_frame, steps, … })` gives `(size, fields)`.
macro_rules! rust_layout {
    ($t:ty { $($f:ident),* $(,)? }) => {{
        let value = <$t as bytemuck::Zeroable>::zeroed();
        let fields: Vec<$crate::nodes::layout::Field> = vec![$((
            stringify!($f),
            std::mem::offset_of!($t, $f),
            std::mem::size_of_val(&value.$f),
        )),*];
        (std::mem::size_of::<$t>(), fields)
    }};
}
pub(crate) use rust_layout;

/// `source` with its imports, as the pipelines compile it, parsed by naga.
fn parse(source: &str) -> Result<naga::Module, String> {
    let source = Wgsl {
        name: "the checked source",
        text: source,
    };
    let composed = compose(&source, ShaderPrecision::Native).text;
    naga::front::wgsl::parse_str(&composed).map_err(|e| e.message().to_string())
}

/// The WGSL struct `name` in `source` (composed with its imports as the pipelines compile it):
/// its span and its members (name, offset, size).
fn wgsl_layout(source: &str, name: &str) -> Result<WgslLayout, String> {
    let module = parse(source)?;
    let ctx = module.to_ctx();
    for (_, ty) in module.types.iter() {
        if ty.name.as_deref() != Some(name) {
            continue;
        }
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            return Err(format!("`{name}` is not a struct"));
        };
        let members = members
            .iter()
            .map(|m| {
                let size = module.types[m.ty].inner.size(ctx) as usize;
                (m.name.clone().unwrap_or_default(), m.offset as usize, size)
            })
            .collect();
        return Ok((*span as usize, members));
    }
    Err(format!("no struct `{name}` in the shader"))
}

/// Every way the Rust layout `(size, fields)` and the WGSL struct `name` of `source` differ.
pub(crate) fn mismatches(
    (size, fields): (usize, Vec<Field>),
    source: &str,
    name: &str,
) -> Vec<String> {
    let (span, members) = match wgsl_layout(source, name) {
        Ok(l) => l,
        Err(e) => return vec![e],
    };
    let mut out = Vec::new();
    // WGSL rounds a struct's size up to its alignment; the buffers hold those trailing bytes
    // (`gpu::wgsl_size`), so the Rust struct may end at its last field.
    if !(size <= span && span as u64 <= crate::gpu::wgsl_size_of(size)) {
        out.push(format!("size: Rust {size} bytes, WGSL `{name}` {span}"));
    }
    let mut sorted = fields.clone();
    sorted.sort_by_key(|f| f.1);
    let mut end = 0;
    for &(field, offset, bytes) in &sorted {
        if offset != end {
            out.push(format!(
                "Rust field `{field}` at {offset}, after a hole from {end}"
            ));
        }
        end = offset + bytes;
    }
    if end != size {
        out.push(format!(
            "the listed Rust fields end at {end}, the struct at {size}"
        ));
    }
    for (member, offset, bytes) in &members {
        match fields.iter().find(|f| f.0 == member) {
            None => out.push(format!("WGSL `{name}.{member}` has no Rust field")),
            Some(&(_, o, b)) if (o, b) != (*offset, *bytes) => out.push(format!(
                "`{member}`: Rust offset {o} size {b}, WGSL offset {offset} size {bytes}"
            )),
            Some(_) => {}
        }
    }
    for &(field, ..) in &fields {
        if !members.iter().any(|m| m.0 == field) {
            out.push(format!("Rust field `{field}` is not in WGSL `{name}`"));
        }
    }
    out
}

/// Asserts that each WGSL `const NAME: u32` of `source` (composed with its imports) has the
/// value the Rust side gives it, listing every difference.
pub(crate) fn assert_constants(source: &str, expected: &[(&str, u32)]) {
    let module = parse(source).expect("the shader parses");
    let mut bad = Vec::new();
    for &(name, value) in expected {
        let found = module
            .constants
            .iter()
            .find(|(_, c)| c.name.as_deref() == Some(name))
            .map(|(_, c)| &module.global_expressions[c.init]);
        match found {
            Some(naga::Expression::Literal(naga::Literal::U32(v))) if *v == value => {}
            other => bad.push(format!("`{name}`: Rust {value}, WGSL {other:?}")),
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// Asserts that the layouts agree, listing every difference.
pub(crate) fn assert_same(rust: (usize, Vec<Field>), source: &str, name: &str) {
    let bad = mismatches(rust, source, name);
    assert!(bad.is_empty(), "WGSL `{name}`:\n{}", bad.join("\n"));
}

#[cfg(test)]
mod tests {
    use super::mismatches;

    #[repr(C)]
    #[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
    struct Probe {
        a: [f32; 4],
        b: u32,
        c: f32,
    }

    /// The check passes a matching struct (24 bytes in Rust, 32 in WGSL, which rounds a struct
    /// with a vector up to 16) and names each kind of difference: swapped members, a member
    /// missing on either side, a wrong size, and a field left out of the list.
    #[test]
    fn the_check_finds_each_kind_of_difference() {
        let layout = || rust_layout!(Probe { a, b, c });
        let wgsl = |body: &str| format!("struct Probe {{ {body} }}\n");
        let good = wgsl("a: vec4<f32>, b: u32, c: f32,");
        assert_eq!(mismatches(layout(), &good, "Probe"), Vec::<String>::new());
        let cases = [
            (wgsl("a: vec4<f32>, c: f32, b: u32,"), "`b`: Rust offset 16"),
            (
                wgsl("a: vec4<f32>, b: u32,"),
                "Rust field `c` is not in WGSL",
            ),
            (
                wgsl("a: vec4<f32>, b: u32, c: f32, d: f32,"),
                "`Probe.d` has no Rust",
            ),
            (
                wgsl("a: vec4<f32>, b: u32, c: f32, d: vec4<f32>,"),
                "size: Rust 24",
            ),
            (
                wgsl("a: vec4<f32>,"),
                "size: Rust 24 bytes, WGSL `Probe` 16",
            ),
            (
                wgsl("a: vec4<f32>, b: u32, c: f32, d: f32,"),
                "`Probe.d` has no Rust",
            ),
            (
                wgsl("a: vec3<f32>, b: u32, c: f32,"),
                "`a`: Rust offset 0 size 16",
            ),
        ];
        for (source, expected) in cases {
            let found = mismatches(layout(), &source, "Probe");
            assert!(
                found.iter().any(|m| m.contains(expected)),
                "{source}: expected {expected:?} in {found:?}"
            );
        }
        let unlisted = rust_layout!(Probe { a, c });
        let found = mismatches(unlisted, &good, "Probe");
        assert!(
            found.iter().any(|m| m.contains("after a hole from 16")),
            "{found:?}"
        );
    }

    /// A constant whose value differs, or that is missing, fails.
    #[test]
    fn the_constant_check_fails_on_a_different_value() {
        let source = "const MODE_A: u32 = 3u;\n";
        super::assert_constants(source, &[("MODE_A", 3)]);
        for wrong in [("MODE_A", 2), ("MODE_B", 3)] {
            let failed = std::panic::catch_unwind(|| super::assert_constants(source, &[wrong]));
            assert!(failed.is_err(), "{wrong:?} passed");
        }
    }
}
