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
use radiosity::photometry::LUMINANCE_WEIGHTS;
use radiosity::solver::adaptive::FAR_FACTOR;
use radiosity::solver::hierarchy::NONE;
use radiosity::solver::hierarchy::transfer::{DIM_SHARE, FAR_RATIO, GRAZE, QUADRATURE_RATIO, Side};

/// Threads of a workgroup of the trace and transfer kernels.
pub const WORKGROUP: u32 = 64;

/// Threads of the book-keeping's workgroups (the shooters' powers take
/// [`WORKGROUP`]).
pub const BOOK_WORKGROUP: u32 = 256;

/// By default, a shooter with at most this many elements has its unshot
/// power summed by one thread (`shooter_powers`); a larger one by a
/// workgroup of [`BOOK_WORKGROUP`] threads (`large_shooter_powers`), so no
/// thread sums more than this many elements or a [`BOOK_WORKGROUP`]th of
/// a shooter's (`GpuBackend::with_serial_power_items`).
pub const SERIAL_POWER_ITEMS: u32 = 64;

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
    /// The most nodes one thread of the receivers' walks visited.
    pub const LONGEST_WALK: usize = 6;
    /// The most nodes one thread of the split walks' items visited.
    pub const LONGEST_ITEM: usize = 7;
    /// [`LONGEST_WALK`] summed over a round's passes, which run one after
    /// another.
    pub const ROUND_LONGEST_WALK: usize = 8;
    /// [`LONGEST_ITEM`] likewise.
    pub const ROUND_LONGEST_ITEM: usize = 9;
    /// Counters in all (the buffer's length).
    pub const COUNTERS: usize = 10;
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
    ("SIDE_FRONT", Value::U32(Side::Front as u32)),
    ("SIDE_BEHIND", Value::U32(Side::Behind as u32)),
    ("SIDE_ACROSS", Value::U32(Side::Across as u32)),
    ("LONGEST_WALK", Value::U32(counter::LONGEST_WALK as u32)),
    ("LONGEST_ITEM", Value::U32(counter::LONGEST_ITEM as u32)),
    (
        "ROUND_LONGEST_WALK",
        Value::U32(counter::ROUND_LONGEST_WALK as u32),
    ),
    (
        "ROUND_LONGEST_ITEM",
        Value::U32(counter::ROUND_LONGEST_ITEM as u32),
    ),
    ("COUNTERS", Value::U32(counter::COUNTERS as u32)),
    ("LUMINANCE_R", Value::F32(LUMINANCE_WEIGHTS[0])),
    ("LUMINANCE_G", Value::F32(LUMINANCE_WEIGHTS[1])),
    ("LUMINANCE_B", Value::F32(LUMINANCE_WEIGHTS[2])),
];

/// One binding of a module's group 0: its WGSL name, address space and
/// type; its number is its place in its table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Binding {
    /// The variable's name in WGSL.
    pub name: &'static str,
    /// `storage, read`, `storage, read_write` or `uniform`.
    pub space: &'static str,
    /// Its WGSL type.
    pub ty: &'static str,
}

/// Declares a module's bindings once: an enum whose variants are the
/// binding numbers (in order from 0, for the host's bind groups) and the
/// table the WGSL declarations are generated from.
macro_rules! bindings {
    ($(#[$doc:meta])* $enum:ident, $table:ident {
        $( $(#[$vdoc:meta])* $variant:ident = $name:literal : $space:literal $ty:literal, )*
    }) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        #[repr(u32)]
        pub enum $enum {
            $( $(#[$vdoc])* $variant, )*
        }

        impl From<$enum> for u32 {
            fn from(binding: $enum) -> u32 {
                binding as u32
            }
        }

        /// The bindings in the order of their numbers.
        pub const $table: &[Binding] = &[
            $( Binding { name: $name, space: $space, ty: $ty }, )*
        ];
    };
}

bindings! {
    /// The trace kernel's bindings (`trace/kernel.wgsl`).
    TraceBinding, TRACE_BINDINGS {
        /// The BVH's nodes.
        Nodes = "nodes": "storage, read" "array<Node>",
        /// Its triangles.
        Triangles = "triangles": "storage, read" "array<Triangle>",
        /// The segments to trace.
        Segments = "segments": "storage, read" "array<Segment>",
        /// Whether each is blocked.
        Blocked = "blocked": "storage, read_write" "array<u32>",
        /// The dispatch's first segment and count.
        Dispatch = "dispatch": "uniform" "Dispatch",
    }
}

bindings! {
    /// The transfer kernels' bindings (`gather/` and `book.wgsl`).
    GatherBinding, GATHER_BINDINGS {
        /// The BVH's nodes (the rays' walk, `trace/walk.wgsl`).
        Nodes = "nodes": "storage, read" "array<Node>",
        /// Its triangles.
        Triangles = "triangles": "storage, read" "array<Triangle>",
        /// The element tree's nodes.
        Tree = "tree": "storage, read" "array<TreeNode>",
        /// The surfaces.
        Surfaces = "surfaces": "storage, read" "array<Surface>",
        /// The elements.
        Elements = "elements": "storage, read" "array<Element>",
        /// The receivers.
        Receivers = "receivers": "storage, read" "array<Receiver>",
        /// Each receiver's irradiance so far (the device's order).
        Total = "total": "storage, read_write" "array<vec4<f32>>",
        /// The shooter's nodes' sources.
        Sources = "sources": "storage, read" "array<NodeSource>",
        /// Their bins.
        Bins = "bins": "storage, read" "array<Bin>",
        /// What each receiver gathers in this shot.
        ShotIrradiance = "shot_irradiance": "storage, read_write" "array<vec4<f32>>",
        /// The shot's parameters.
        Shot = "shot": "uniform" "Shot",
        /// What the walks counted ([`counter`]).
        Counters = "counters": "storage, read_write" "array<atomic<u32>, COUNTERS>",
        /// Glass: the panes' triangles (one of no area when there is none).
        Panes = "panes": "storage, read" "array<Pane>",
        /// The split walks of one chunk of receivers: first a header a
        /// receiver of the chunk (x: its first item, y: how many), then the
        /// items (before `gather_items`: x the subtree's node, y the
        /// receiver; after it, xyz the bits of what the subtree sends).
        Split = "split": "storage, read_write" "array<vec4<u32>>",
        /// The workgroups `gather_items` is dispatched with (indirect).
        ItemDispatch = "item_dispatch": "storage, read_write" "array<u32, 3>",
        /// Each element's unshot radiosity.
        Unshot = "unshot": "storage, read_write" "array<vec4<f32>>",
        /// Each element's book-keeping data.
        ElementBook = "element_book": "storage, read" "array<ElementBook>",
        /// Each workgroup's share of the ledger.
        Partials = "partials": "storage, read_write" "array<Partial>",
        /// Each shooter's range of `items`.
        ShooterItems = "shooter_items": "storage, read" "array<vec2<u32>>",
        /// The shooters' elements.
        Items = "items": "storage, read" "array<u32>",
        /// Each shooter's unshot power.
        Powers = "powers": "storage, read_write" "array<f32>",
        /// The unshot radiosity of the elements the host asked for.
        Staging = "staging": "storage, read_write" "array<vec4<f32>>",
        /// The elements whose unshot radiosity the host asks for.
        Wanted = "wanted": "storage, read" "array<u32>",
        /// What the round's shooters' elements are left with.
        Leaves = "leaves": "storage, read" "array<Leave>",
        /// What each receiver has gathered in this round so far.
        RoundIrradiance = "round_irradiance": "storage, read_write" "array<vec4<f32>>",
        /// Its direct part.
        RoundDirect = "round_direct": "storage, read_write" "array<vec4<f32>>",
        /// The book-keeping pass's parameters.
        Book = "book": "uniform" "Book",
        /// Each receiver's direct irradiance: the lights' and the emitting
        /// surfaces' first shots.
        DirectTotal = "direct_total": "storage, read_write" "array<vec4<f32>>",
        /// The next round as the device chooses it (`choose_next`): the
        /// brightest shooter at 0, the shooters chosen at 1, their
        /// elements at 2.
        Next = "next": "storage, read_write" "array<u32, 4>",
        /// Each chosen shooter's first element in the next round's list
        /// (`NONE` for the others).
        RoundOffsets = "round_offsets": "storage, read_write" "array<u32>",
        /// The shooter of each of the element tree's items (`NONE` for
        /// none).
        ItemShooter = "item_shooter": "storage, read" "array<u32>",
        /// The next round's elements' unshot radiosity (`collect_next`),
        /// read back with the round's ledger.
        NextUnshot = "next_unshot": "storage, read_write" "array<vec4<f32>>",
        /// The shooters whose powers a workgroup each sums (more than
        /// [`SERIAL_POWER_ITEMS`] elements, by default).
        LargeShooters = "large_shooters": "storage, read" "array<u32>",
    }
}

/// The WGSL declarations of `table`'s bindings, in group 0.
#[must_use]
pub fn declarations(table: &[Binding]) -> String {
    let mut out = String::from("// Generated from shaders.rs's table: not by hand.\n");
    for (i, b) in table.iter().enumerate() {
        let _ = writeln!(
            out,
            "@group(0) @binding({i}) var<{}> {}: {};",
            b.space, b.name, b.ty
        );
    }
    out
}

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

/// The trace kernel's files: the scene and its walk, the kernel.
pub const TRACE_FILES: [(&str, &str); 2] = [
    ("trace/walk.wgsl", include_str!("trace/walk.wgsl")),
    ("trace/kernel.wgsl", include_str!("trace/kernel.wgsl")),
];

/// The transfer kernels' files, one an idea: the rays' walk, the polygon
/// rules (clipping, Newell's normal, the analytic factor), the buffers'
/// structs, what passes along a ray (shadow, glass), the point and element
/// factors, a node's placement and quadrature, the walk of the element
/// tree and its entry points, the book-keeping.
pub const GATHER_FILES: [(&str, &str); 8] = [
    ("trace/walk.wgsl", include_str!("trace/walk.wgsl")),
    ("gather/polygon.wgsl", include_str!("gather/polygon.wgsl")),
    ("gather/structs.wgsl", include_str!("gather/structs.wgsl")),
    (
        "gather/visibility.wgsl",
        include_str!("gather/visibility.wgsl"),
    ),
    ("gather/factors.wgsl", include_str!("gather/factors.wgsl")),
    (
        "gather/placement.wgsl",
        include_str!("gather/placement.wgsl"),
    ),
    ("gather/walk.wgsl", include_str!("gather/walk.wgsl")),
    ("gather/book.wgsl", include_str!("gather/book.wgsl")),
];

/// The trace kernel's module source: the prelude, its bindings, its files.
#[must_use]
pub fn trace_source() -> String {
    prelude() + &declarations(TRACE_BINDINGS) + &TRACE_FILES.map(|f| f.1).concat()
}

/// The transfer kernels' module source: the prelude, their bindings, their
/// files.
#[must_use]
pub fn gather_source() -> String {
    prelude() + &declarations(GATHER_BINDINGS) + &GATHER_FILES.map(|f| f.1).concat()
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
        let all = GATHER_FILES.map(|f| f.1).concat()
            + &TRACE_FILES.map(|f| f.1).concat()
            + &declarations(GATHER_BINDINGS)
            + &declarations(TRACE_BINDINGS);
        for (file, text) in GATHER_FILES.iter().chain(&TRACE_FILES) {
            assert!(
                !text.contains("@binding("),
                "{file} declares a binding by hand: bindings are shaders.rs's tables"
            );
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
        let files = GATHER_FILES.map(|f| f.1).concat() + &TRACE_FILES.map(|f| f.1).concat();
        for b in GATHER_BINDINGS.iter().chain(TRACE_BINDINGS) {
            assert!(
                files.contains(&format!("{}[", b.name)) || files.contains(&format!("{}.", b.name)),
                "the binding {} is declared but no kernel uses it",
                b.name
            );
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
