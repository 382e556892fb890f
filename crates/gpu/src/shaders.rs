//! The kernels' WGSL source, put together in one place. Every number a
//! kernel shares with the Rust code (the transfer rules' ratios and
//! tolerances of Wallace, Elmquist & Haines 1989's point-to-area transfer
//! as the default method refines it, the analytic factor's tolerances of
//! Baum et al. (Wong & Tsang 1993, section 4), the BVH's node layout, the
//! workgroup sizes, the counters' places) is defined once, in Rust, and
//! reaches WGSL through a generated prelude of `const` declarations
//! ([`prelude`]); no `.wgsl` file writes one by hand (the test
//! `no_number_is_written_twice` checks it). The source files follow, one
//! concatenation a module ([`trace_source`], [`gather_source`]).

use std::fmt::Write as _;

use radiosity::accel::SEGMENT_EPSILON;
use radiosity::accel::bvh::FLAT_INTERIOR;
use radiosity::form_factor::analytic::{DEGENERATE, ON_PLANE};
use radiosity::solver::adaptive::FAR_FACTOR;
use radiosity::solver::hierarchy::NONE;
use radiosity::solver::hierarchy::transfer::{DIM_SHARE, FAR_RATIO, GRAZE, QUADRATURE_RATIO};

/// Threads of a workgroup of the trace and transfer kernels.
pub const WORKGROUP: u32 = 64;

/// Threads of the book-keeping's workgroups (the shooters' powers take
/// [`WORKGROUP`]).
pub const BOOK_WORKGROUP: u32 = 256;

/// Entries of the transfer kernel's walk stack: the deepest element tree
/// it holds is two less (a visit pushes two children).
pub const WALK_STACK: u32 = 64;

/// Entries of the trace kernel's stack: the depth the BVH's build
/// bounds.
pub const TRACE_STACK: u32 = radiosity::accel::bvh::MAX_DEPTH as u32;

/// The largest frontier a split walk keeps (its ring of nodes).
pub const MAX_FRONTIER: u32 = 64;

/// The places of the counters the walks sum, and how many there are.
pub mod counter {
    /// Receiver-source pairs.
    pub const PAIRS: usize = 0;
    /// Shadow rays.
    pub const RAYS: usize = 1;
    /// Walks (a receiver's, or an item's).
    pub const WALKS: usize = 2;
    /// Nodes visited.
    pub const VISITS: usize = 3;
    /// Element sources integrated.
    pub const ELEMENTS: usize = 4;
    /// The items the chunk's split walks hold so far.
    pub const ITEMS: usize = 5;
    /// Counters in all (the buffer's length; two spare).
    pub const COUNTERS: usize = 8;
}

/// A shared number's WGSL type and value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    /// An `f32`, from the Rust `f64` (rounded once, by the shader compiler
    /// as by `as f32`).
    F32(f64),
    /// A `u32`.
    U32(u32),
}

/// Every number the kernels share with Rust, by its WGSL name.
pub const SHARED: &[(&str, Value)] = &[
    ("PI", Value::F32(std::f64::consts::PI)),
    ("TAU", Value::F32(std::f64::consts::TAU)),
    ("NONE", Value::U32(NONE)),
    ("FAR_RATIO", Value::F32(FAR_RATIO)),
    ("FAR_FACTOR", Value::F32(FAR_FACTOR)),
    ("QUADRATURE_RATIO", Value::F32(QUADRATURE_RATIO)),
    ("GRAZE", Value::F32(GRAZE)),
    ("DIM_SHARE", Value::F32(DIM_SHARE)),
    ("SEGMENT_EPSILON", Value::F32(SEGMENT_EPSILON)),
    ("DEGENERATE", Value::F32(DEGENERATE)),
    ("ON_PLANE", Value::F32(ON_PLANE)),
    ("INTERIOR", Value::U32(FLAT_INTERIOR)),
    ("WORKGROUP", Value::U32(WORKGROUP)),
    ("BOOK_WORKGROUP", Value::U32(BOOK_WORKGROUP)),
    ("WALK_STACK", Value::U32(WALK_STACK)),
    ("STACK_SIZE", Value::U32(TRACE_STACK)),
    ("RING", Value::U32(MAX_FRONTIER)),
    ("PAIRS", Value::U32(counter::PAIRS as u32)),
    ("RAYS", Value::U32(counter::RAYS as u32)),
    ("WALKS", Value::U32(counter::WALKS as u32)),
    ("VISITS", Value::U32(counter::VISITS as u32)),
    ("ELEMENTS", Value::U32(counter::ELEMENTS as u32)),
    ("ITEMS", Value::U32(counter::ITEMS as u32)),
];

/// The `const` declarations of [`SHARED`], one a line.
#[must_use]
pub fn prelude() -> String {
    let mut out = String::from("// Generated from the Rust constants (shaders.rs): not by hand.\n");
    for (name, value) in SHARED {
        let _ = match value {
            // `{:?}` of an f32 is the shortest text that reads back as it,
            // with a point or an exponent, as WGSL wants.
            Value::F32(v) => writeln!(out, "const {name}: f32 = {:?};", *v as f32),
            Value::U32(v) => writeln!(out, "const {name}: u32 = {v}u;"),
        };
    }
    out
}

/// The trace kernel's files (shadow segments against the scene's BVH).
pub const TRACE_FILES: [(&str, &str); 1] = [("trace.wgsl", include_str!("trace.wgsl"))];

/// The transfer kernels' files: the trace kernel's walk, the polygon
/// rules, the walk of the element tree, the book-keeping.
pub const GATHER_FILES: [(&str, &str); 4] = [
    ("trace.wgsl", include_str!("trace.wgsl")),
    ("gather/polygon.wgsl", include_str!("gather/polygon.wgsl")),
    ("gather/gather.wgsl", include_str!("gather/gather.wgsl")),
    ("gather/book.wgsl", include_str!("gather/book.wgsl")),
];

/// The trace kernel's module source.
#[must_use]
pub fn trace_source() -> String {
    prelude() + &TRACE_FILES.map(|f| f.1).concat()
}

/// The transfer kernels' module source.
#[must_use]
pub fn gather_source() -> String {
    prelude() + &GATHER_FILES.map(|f| f.1).concat()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The names of the `const` items a text declares at the start of a
    /// line (Rust `pub const`, `const`, WGSL `const`).
    fn declared(text: &str) -> Vec<String> {
        text.lines()
            .filter_map(|line| {
                let line = line.trim_start();
                let line = line
                    .strip_prefix("pub(crate) ")
                    .or_else(|| line.strip_prefix("pub(super) "))
                    .or_else(|| line.strip_prefix("pub "))
                    .unwrap_or(line);
                let rest = line.strip_prefix("const ")?;
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                (!name.is_empty()).then_some(name)
            })
            .collect()
    }

    /// No `.wgsl` file declares a constant the prelude gives, and every
    /// constant a `.wgsl` file does declare has no Rust constant of its
    /// name in this crate or the core library (where it would be a twin
    /// kept equal by hand); every shared number is used.
    #[test]
    fn no_number_is_written_twice() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut rust = Vec::new();
        for dir in [root.join("src"), root.join("../radiosity/src")] {
            let mut stack = vec![dir];
            while let Some(dir) = stack.pop() {
                for entry in std::fs::read_dir(&dir).unwrap() {
                    let path = entry.unwrap().path();
                    if path.is_dir() {
                        stack.push(path);
                    } else if path.extension().is_some_and(|e| e == "rs")
                        && !path.ends_with("shaders.rs")
                    {
                        rust.extend(declared(&std::fs::read_to_string(&path).unwrap()));
                    }
                }
            }
        }
        let shared: Vec<&str> = SHARED.iter().map(|s| s.0).collect();
        let all = GATHER_FILES.map(|f| f.1).concat();
        for (file, text) in GATHER_FILES {
            for name in declared(text) {
                assert!(
                    !shared.contains(&name.as_str()),
                    "{file} declares {name}, which the prelude gives"
                );
                assert!(
                    !rust.contains(&name),
                    "{file} declares {name} by hand, and a Rust constant has that name: \
                     give it through shaders.rs"
                );
            }
        }
        for name in shared {
            let used = all.match_indices(name).any(|(i, _)| {
                !all[i + name.len()..].starts_with(|c: char| c.is_ascii_alphanumeric() || c == '_')
            });
            assert!(used, "{name} is shared but no kernel uses it");
        }
    }

    /// The prelude's text: f32 values as they read back, u32 with their
    /// suffix.
    #[test]
    fn the_prelude_writes_wgsl() {
        let text = prelude();
        assert!(text.contains("const FAR_RATIO: f32 = 3.0;"), "{text}");
        assert!(text.contains("const GRAZE: f32 = 0.0625;"), "{text}");
        assert!(
            text.contains("const SEGMENT_EPSILON: f32 = 1e-6;"),
            "{text}"
        );
        assert!(
            text.contains("const INTERIOR: u32 = 2147483648u;"),
            "{text}"
        );
        naga::front::wgsl::parse_str(&gather_source()).unwrap();
        naga::front::wgsl::parse_str(&trace_source()).unwrap();
    }
}
