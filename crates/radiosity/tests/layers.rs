//! The core library's floor plan (conventions.md, "Folders follow the
//! pipeline"): every path from one top module of `crates/radiosity/src`
//! to another (a `use` line or a path inline, `crate::...` or a chain of
//! `super::` that leaves its module) points down the table of layers, and
//! no two top modules reach each other. Test code (`#[cfg(test)]` items)
//! and comments are not read: a test may reach anywhere, a doc link names
//! what it explains.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The table of layers: a top module may use its own layer's and those
/// below.
const LAYERS: &[(u32, &[&str])] = &[
    (1, &["geometry", "photometry", "choice"]),
    (2, &["scene"]),
    (3, &["mesh", "accel", "hemicube"]),
    (4, &["form_factor"]),
    (5, &["solver"]),
    (6, &["final_gather", "render", "sensors", "export", "view"]),
    (7, &["app", "memory"]),
];

fn layer(top: &str) -> Option<u32> {
    LAYERS
        .iter()
        .find(|(_, names)| names.contains(&top))
        .map(|(l, _)| *l)
}

/// `text` with comments, string and character literals blanked (their
/// newlines kept, so lines still count), then every `#[cfg(test)]` item.
fn code_only(text: &str) -> String {
    let chars: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let blank = |c: char| if c == '\n' { '\n' } else { ' ' };
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let next = chars.get(i + 1).copied();
        if c == '/' && next == Some('/') {
            while i < chars.len() && chars[i] != '\n' {
                out.push(' ');
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            let mut depth = 0;
            while i < chars.len() {
                if chars[i] == '/' && chars.get(i + 1) == Some(&'*') {
                    depth += 1;
                    out.push_str("  ");
                    i += 2;
                } else if chars[i] == '*' && chars.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    out.push_str("  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    out.push(blank(chars[i]));
                    i += 1;
                }
            }
        } else if c == 'r'
            && (next == Some('#') || next == Some('"'))
            && !ident_char(prev(&chars, i))
        {
            // A raw string: r"..." or r#"..."#.
            let mut j = i + 1;
            let mut hashes = 0;
            while chars.get(j) == Some(&'#') {
                hashes += 1;
                j += 1;
            }
            if chars.get(j) != Some(&'"') {
                out.push(c);
                i += 1;
                continue;
            }
            j += 1;
            loop {
                if j >= chars.len() {
                    break;
                }
                if chars[j] == '"' && (0..hashes).all(|h| chars.get(j + 1 + h) == Some(&'#')) {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            for &k in &chars[i..j.min(chars.len())] {
                out.push(blank(k));
            }
            i = j;
        } else if c == '"' {
            out.push(' ');
            i += 1;
            while i < chars.len() && chars[i] != '"' {
                if chars[i] == '\\' {
                    out.push(' ');
                    i += 1;
                }
                if i < chars.len() {
                    out.push(blank(chars[i]));
                    i += 1;
                }
            }
            out.push(' ');
            i += 1;
        } else if c == '\'' {
            // A character literal ('x', '\n', '\u{..}'), not a lifetime.
            let close = if next == Some('\\') {
                (i + 2..chars.len().min(i + 12)).find(|&j| chars[j] == '\'')
            } else if chars.get(i + 2) == Some(&'\'') {
                Some(i + 2)
            } else {
                None
            };
            match close {
                Some(j) => {
                    for _ in i..=j {
                        out.push(' ');
                    }
                    i = j + 1;
                }
                None => {
                    out.push(c);
                    i += 1;
                }
            }
        } else {
            out.push(c);
            i += 1;
        }
    }
    strip_test_items(&out)
}

fn prev(chars: &[char], i: usize) -> char {
    if i == 0 { ' ' } else { chars[i - 1] }
}

fn ident_char(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// `code` (comments and literals blanked) with each item under
/// `#[cfg(test)]` blanked: to its matching brace, or to its `;`.
fn strip_test_items(code: &str) -> String {
    let mut chars: Vec<char> = code.chars().collect();
    let marker: Vec<char> = "#[cfg(test)]".chars().collect();
    let mut i = 0;
    while i + marker.len() <= chars.len() {
        if chars[i..i + marker.len()] != marker[..] {
            i += 1;
            continue;
        }
        let mut j = i + marker.len();
        let mut end = chars.len();
        while j < chars.len() {
            if chars[j] == ';' {
                end = j + 1;
                break;
            }
            if chars[j] == '{' {
                let mut depth = 0;
                while j < chars.len() {
                    match chars[j] {
                        '{' => depth += 1,
                        '}' => {
                            depth -= 1;
                            if depth == 0 {
                                break;
                            }
                        }
                        _ => {}
                    }
                    j += 1;
                }
                end = (j + 1).min(chars.len());
                break;
            }
            j += 1;
        }
        for c in &mut chars[i..end] {
            if *c != '\n' {
                *c = ' ';
            }
        }
        i = end;
    }
    chars.into_iter().collect()
}

/// The module path of a source file relative to `src` (`solver/mod.rs`:
/// `["solver"]`, `solver/adaptive/gather.rs`:
/// `["solver", "adaptive", "gather"]`).
fn module_path(relative: &Path) -> Vec<String> {
    let mut parts: Vec<String> = relative
        .iter()
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap_or_default();
    let stem = last.trim_end_matches(".rs");
    if stem != "mod" && stem != "lib" {
        parts.push(stem.to_string());
    }
    parts
}

/// Every top module a path in `code` names, with its line: `crate::x`,
/// `crate::{x, y::z}` (each at the line of its name), and `super::`
/// chains from `module` that climb to the crate's root and down again.
fn paths(code: &str, module: &[String]) -> Vec<(String, usize)> {
    let chars: Vec<char> = code.chars().collect();
    let line_at = |i: usize| chars[..i].iter().filter(|&&c| c == '\n').count() + 1;
    let mut found = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let boundary = !ident_char(prev(&chars, i)) && prev(&chars, i) != ':';
        if boundary && word_at(&chars, i, "crate") && sep_at(&chars, i + 5) {
            collect_tops(&chars, i + 7, &mut found, &line_at);
            i += 7;
            continue;
        }
        if boundary && word_at(&chars, i, "super") {
            // `super` from a file's module is its parent; a chain that
            // reaches the crate's root names a top module next.
            let mut depth = module.len();
            let mut j = i;
            while word_at(&chars, j, "super") && sep_at(&chars, j + 5) {
                depth = depth.saturating_sub(1);
                j += 7;
            }
            if j > i && depth == 0 {
                collect_tops(&chars, j, &mut found, &line_at);
            }
            i = j.max(i + 5);
            continue;
        }
        i += 1;
    }
    found
}

fn word_at(chars: &[char], i: usize, word: &str) -> bool {
    let w: Vec<char> = word.chars().collect();
    i + w.len() <= chars.len()
        && chars[i..i + w.len()] == w[..]
        && !chars.get(i + w.len()).is_some_and(|c| ident_char(*c))
}

fn sep_at(chars: &[char], i: usize) -> bool {
    chars.get(i) == Some(&':') && chars.get(i + 1) == Some(&':')
}

/// The top module names at `i` (just after `crate::`): one identifier, or
/// the first identifier of each item of a `{...}` group.
fn collect_tops(
    chars: &[char],
    mut i: usize,
    found: &mut Vec<(String, usize)>,
    line_at: &dyn Fn(usize) -> usize,
) {
    while chars.get(i).is_some_and(|c| c.is_whitespace()) {
        i += 1;
    }
    if chars.get(i) == Some(&'{') {
        let mut depth = 0;
        let mut item_start = true;
        while i < chars.len() {
            let c = chars[i];
            match c {
                '{' => {
                    depth += 1;
                    if depth == 1 {
                        item_start = true;
                    }
                }
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        break;
                    }
                }
                ',' if depth == 1 => item_start = true,
                c if depth == 1 && item_start && ident_char(c) => {
                    let start = i;
                    while i < chars.len() && ident_char(chars[i]) {
                        i += 1;
                    }
                    let name: String = chars[start..i].iter().collect();
                    found.push((name, line_at(start)));
                    item_start = false;
                    continue;
                }
                _ => {}
            }
            i += 1;
        }
    } else {
        let start = i;
        while i < chars.len() && ident_char(chars[i]) {
            i += 1;
        }
        if i > start {
            found.push((chars[start..i].iter().collect(), line_at(start)));
        }
    }
}

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Every edge between two top modules: `(from, to) -> (file, line)` of
/// its first path, and every path whose target is not in the table.
type Edges = BTreeMap<(String, String), (String, usize)>;

fn edges(src: &Path) -> (Edges, Vec<String>) {
    let mut files = Vec::new();
    sources(src, &mut files);
    files.sort();
    let mut edges = Edges::new();
    let mut unknown = Vec::new();
    let tops: BTreeSet<String> = std::fs::read_dir(src)
        .unwrap()
        .map(|e| {
            e.unwrap()
                .path()
                .file_stem()
                .unwrap()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    for file in files {
        let relative = file.strip_prefix(src).unwrap().to_path_buf();
        let module = module_path(&relative);
        let Some(from) = module.first().cloned() else {
            continue;
        };
        let code = code_only(&std::fs::read_to_string(&file).unwrap());
        for (to, line) in paths(&code, &module) {
            // Items of the crate's root (`crate::luminance`, a
            // re-export) are not modules.
            if !tops.contains(&to) || to == from {
                continue;
            }
            let at = format!("{}:{line}", relative.display());
            if layer(&to).is_none() || layer(&from).is_none() {
                unknown.push(format!(
                    "{at}: {from} -> {to}: a top module not in the table"
                ));
                continue;
            }
            edges.entry((from.clone(), to)).or_insert((at, line));
        }
    }
    (edges, unknown)
}

#[test]
fn imports_point_down_the_table_of_layers_and_close_no_circle() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let (edges, mut problems) = edges(&src);
    assert!(edges.len() > 40, "only {} edges read", edges.len());
    for ((from, to), (at, _)) in &edges {
        let (lf, lt) = (layer(from).unwrap(), layer(to).unwrap());
        if lt > lf {
            problems.push(format!(
                "{at}: {from} (layer {lf}) uses {to} (layer {lt}), up the table"
            ));
        }
    }
    // Circles: two top modules each reaching the other.
    let reach = |a: &str| -> BTreeSet<String> {
        let mut seen = BTreeSet::new();
        let mut stack = vec![a.to_string()];
        while let Some(x) = stack.pop() {
            for (f, t) in edges.keys() {
                if *f == x && seen.insert(t.clone()) {
                    stack.push(t.clone());
                }
            }
        }
        seen
    };
    // A circle through a path up the table is reported as that path; one
    // within a layer here, at the first step of each way round.
    let names: BTreeSet<&String> = edges.keys().map(|(f, _)| f).collect();
    let step = |from: &str, to: &str| {
        edges
            .iter()
            .find(|((f, t), _)| f == from && (t == to || reach(t).contains(to)))
            .map_or(String::new(), |(_, (at, _))| at.clone())
    };
    for a in &names {
        for b in reach(a) {
            if a.as_str() < b.as_str() && layer(a) == layer(&b) && reach(&b).contains(a.as_str()) {
                problems.push(format!(
                    "{} and {}: {a} and {b} reach each other (a circle)",
                    step(a, &b),
                    step(&b, a)
                ));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The reader of paths: grouped imports over lines, inline paths,
/// comments, strings and test modules.
#[test]
fn the_reader_finds_grouped_inline_and_super_paths_but_not_comments_or_tests() {
    let text = "use crate::{\n    scene::Scene,\n    solver::{self, Solver},\n};\n\
        // crate::app in a comment\n\
        /// [`crate::render`] in a doc\n\
        fn f() { let s = \"crate::export\"; crate::accel::shorten(a, b); let c = '\"'; }\n\
        #[cfg(test)]\nmod tests { use crate::memory; }\n\
        fn g<'a>(x: &'a str) { super::super::view::x(); }\n";
    let module = vec!["final_gather".to_string(), "direct".to_string()];
    let code = code_only(text);
    let found: Vec<(String, usize)> = paths(&code, &module);
    let names: Vec<&str> = found.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["scene", "solver", "accel", "view"], "{found:?}");
    assert_eq!(found[1].1, 3);
    assert_eq!(found[2].1, 7);
}
