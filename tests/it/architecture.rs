//! The layering holds: within each crate of the workspace the top-level modules import
//! one another without a cycle, and so do the modules of each folder. Read from the
//! sources: every `crate::` and `super::` path outside comments and test modules names
//! the module it reaches, and a module reaching a sibling (or anything inside one) is an
//! edge between the two siblings.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The crates' source folders.
const CRATES: &[&str] = &[
    "crates/core/src",
    "crates/io/src",
    "crates/map/src",
    "crates/py/src",
    "crates/sim/src",
    "src",
];

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// A file's module path (`["levelset", "warm"]`; the crate root is empty).
fn module_of(root: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(root).unwrap().with_extension("");
    let mut parts: Vec<String> = rel.iter().map(|c| c.to_string_lossy().into()).collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    parts
}

/// The text of a file without its comments and without its test-only items (the tests
/// may reach anywhere): every item under `#[cfg(test)]`, a module written inline (to its
/// matching brace) or in a file of its own (`mod NAME;`, whose file [`test_files`]
/// leaves out), a function or a `use`, wherever it stands in the file.
fn code(text: &str) -> String {
    let text: String = text
        .lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n");
    let mut out = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(i) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..i]);
        rest = &rest[i + "#[cfg(test)]".len()..];
        // The item ends at its first `;` before any `{`, or at the brace that closes
        // its first `{`.
        let (mut depth, mut end) = (0usize, rest.len());
        for (k, c) in rest.char_indices() {
            match c {
                ';' if depth == 0 => {
                    end = k + 1;
                    break;
                }
                '{' => depth += 1,
                '}' => {
                    depth = depth.saturating_sub(1);
                    if depth == 0 {
                        end = k + 1;
                        break;
                    }
                }
                _ => {}
            }
        }
        rest = &rest[end..];
    }
    out.push_str(rest);
    out
}

/// The files of modules declared under `#[cfg(test)]` as `mod NAME;` in `file` (`NAME.rs`
/// or `NAME/mod.rs` beside a `mod.rs`/`lib.rs`/`main.rs`, else in the file's own folder).
fn test_files(file: &Path, text: &str) -> Vec<PathBuf> {
    let dir = match file.file_stem().and_then(|s| s.to_str()) {
        Some("mod" | "lib" | "main") => file.parent().unwrap().to_path_buf(),
        _ => file.with_extension(""),
    };
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(i) = rest.find("#[cfg(test)]") {
        rest = &rest[i + "#[cfg(test)]".len()..];
        let item = rest.trim_start();
        let item = item.strip_prefix("pub(crate) ").unwrap_or(item);
        if let Some(decl) = item.strip_prefix("mod ") {
            let name = decl
                .split(|c: char| !(c.is_alphanumeric() || c == '_'))
                .next();
            if let Some(name) = name.filter(|n| decl[n.len()..].trim_start().starts_with(';')) {
                out.push(dir.join(format!("{name}.rs")));
                out.push(dir.join(name).join("mod.rs"));
            }
        }
    }
    out
}

/// The names each module re-exports with `pub use`, inline modules' included: a path
/// through a re-export (`crate::Params`, `crate::stages::Prepared`) reaches the module the
/// name is defined in. Name to the absolute path it stands for.
fn exports(
    code: &str,
    me: &[String],
    modules: &BTreeSet<Vec<String>>,
) -> BTreeMap<String, Vec<String>> {
    let mut out = BTreeMap::new();
    for stmt in code.split(';') {
        let Some(i) = stmt.find("pub use ") else {
            continue;
        };
        let tree = stmt[i + 8..].trim();
        let (base, rest) = match absolute(tree, me) {
            Some(br) => br,
            None => {
                // Relative to the module: a child of it, or another crate.
                let tree = tree.strip_prefix("self::").unwrap_or(tree);
                let first = tree.split("::").next().unwrap_or("").trim().to_string();
                let mut child = me.to_vec();
                child.push(first);
                if !modules.contains(&child) {
                    continue;
                }
                (me.to_vec(), tree.to_string())
            }
        };
        for p in expand(&rest) {
            let Some(last) = p.last().cloned() else {
                continue;
            };
            // `X as Y` is expanded as `X`; the alias is the word after `as`.
            let alias = rest
                .split([',', '{', '}'])
                .map(str::trim)
                .find_map(|part| {
                    let (name, alias) = part.split_once(" as ")?;
                    (name.trim().rsplit("::").next()? == last).then(|| alias.trim().to_string())
                })
                .unwrap_or_else(|| last.clone());
            out.insert(alias, base.iter().cloned().chain(p).collect());
        }
    }
    out
}

/// The paths a use tree names: `a::{b, c::d}` gives `a::b` and `a::c::d`.
fn expand(tree: &str) -> Vec<Vec<String>> {
    fn rec(prefix: &[String], s: &str, out: &mut Vec<Vec<String>>) {
        let s = s.trim();
        if s.is_empty() {
            return;
        }
        if let Some(inner) = s.strip_prefix('{') {
            let inner = &inner[..inner.rfind('}').unwrap_or(inner.len())];
            let (mut depth, mut start) = (0, 0);
            for (i, c) in inner.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        rec(prefix, &inner[start..i], out);
                        start = i + 1;
                    }
                    _ => {}
                }
            }
            rec(prefix, &inner[start..], out);
            return;
        }
        match s.split_once("::") {
            Some((head, rest)) => {
                let mut p = prefix.to_vec();
                p.push(head.trim().into());
                rec(&p, rest, out);
            }
            None => {
                let mut p = prefix.to_vec();
                let name = s.split_whitespace().next().unwrap_or("");
                p.push(name.into());
                out.push(p);
            }
        }
    }
    let mut out = Vec::new();
    rec(&[], tree, &mut out);
    out
}

/// The absolute module path of `path` (which starts with `crate::` or `super::`, as
/// often as it goes up) written in module `me`.
fn absolute(path: &str, me: &[String]) -> Option<(Vec<String>, String)> {
    if let Some(rest) = path.strip_prefix("crate::") {
        return Some((Vec::new(), rest.to_string()));
    }
    let mut base = me.to_vec();
    let mut rest = path;
    let mut up = false;
    while let Some(r) = rest.strip_prefix("super::") {
        base.pop()?;
        rest = r;
        up = true;
    }
    up.then(|| (base, rest.to_string()))
}

/// Every module path a file's code reaches through `crate::` or `super::`.
fn reached(code: &str, me: &[String]) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    // `use` declarations, whose trees may span lines.
    for stmt in code.split(';') {
        let Some(i) = stmt.find("use ") else { continue };
        if let Some((base, rest)) = absolute(stmt[i + 4..].trim(), me) {
            for p in expand(&rest) {
                out.push(base.iter().cloned().chain(p).collect());
            }
        }
    }
    // Paths in expressions and types.
    for prefix in ["crate::", "super::"] {
        let mut from = 0;
        while let Some(i) = code[from..].find(prefix) {
            let at = from + i;
            from = at + prefix.len();
            let before = code[..at].chars().next_back();
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                continue;
            }
            let text = code[at..]
                .split(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                .next()
                .unwrap_or("");
            if let Some((base, rest)) = absolute(text, me) {
                let path = rest.split("::").filter(|s| !s.is_empty()).map(String::from);
                out.push(base.into_iter().chain(path).collect());
            }
        }
    }
    out
}

/// A cycle among `nodes` under `edges`, if any (depth-first search).
fn cycle(edges: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        v: &str,
        edges: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        state.insert(v.into(), 1);
        stack.push(v.into());
        for w in edges.get(v).into_iter().flatten() {
            match state.get(w.as_str()).copied().unwrap_or(0) {
                0 => {
                    if let Some(c) = visit(w, edges, state, stack) {
                        return Some(c);
                    }
                }
                1 => {
                    let from = stack.iter().position(|s| s == w).unwrap();
                    let mut c = stack[from..].to_vec();
                    c.push(w.clone());
                    return Some(c);
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(v.into(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for v in edges.keys() {
        if state.get(v.as_str()).copied().unwrap_or(0) == 0 {
            if let Some(c) = visit(v, edges, &mut state, &mut Vec::new()) {
                return Some(c);
            }
        }
    }
    None
}

/// The cycles among the children of every folder of the crate at `root`.
fn cycles(root: &Path) -> Vec<String> {
    let mut files = Vec::new();
    sources(root, &mut files);
    let texts: Vec<String> = files
        .iter()
        .map(|f| std::fs::read_to_string(f).unwrap())
        .collect();
    let tests: BTreeSet<PathBuf> = files
        .iter()
        .zip(&texts)
        .flat_map(|(f, t)| test_files(f, t))
        .collect();
    let (files, texts): (Vec<PathBuf>, Vec<String>) = files
        .into_iter()
        .zip(texts)
        .filter(|(f, _)| !tests.contains(f))
        .unzip();
    let modules: BTreeSet<Vec<String>> = files.iter().map(|f| module_of(root, f)).collect();
    let codes: Vec<String> = texts.iter().map(|t| code(t)).collect();
    let exported: BTreeMap<Vec<String>, BTreeMap<String, Vec<String>>> = files
        .iter()
        .zip(&codes)
        .map(|(f, c)| {
            let me = module_of(root, f);
            let e = exports(c, &me, &modules);
            (me, e)
        })
        .collect();
    // The module a path reaches: the deepest module it names, or, when it goes on past
    // a module through a name that module re-exports, where that name is defined.
    let resolve = |path: &[String]| -> Option<Vec<String>> {
        let mut path = path.to_vec();
        let mut m = Vec::new();
        for _ in 0..8 {
            m = (0..=path.len())
                .rev()
                .map(|k| path[..k].to_vec())
                .find(|p| modules.contains(p))?;
            let through = path[m.len()..]
                .iter()
                .find_map(|name| exported.get(&m).and_then(|e| e.get(name)));
            match through {
                Some(target) if *target != path => path = target.clone(),
                _ => break,
            }
        }
        Some(m)
    };
    // Module to module, every reach.
    let mut reach: Vec<(Vec<String>, Vec<String>)> = Vec::new();
    for (f, c) in files.iter().zip(&codes) {
        let me = module_of(root, f);
        for p in reached(c, &me) {
            if let Some(m) = resolve(&p) {
                if m != me {
                    reach.push((me.clone(), m));
                }
            }
        }
    }
    let mut found = Vec::new();
    let parents: BTreeSet<Vec<String>> = modules
        .iter()
        .filter(|m| !m.is_empty())
        .map(|m| m[..m.len() - 1].to_vec())
        .collect();
    for parent in parents {
        let n = parent.len();
        let child = |m: &[String]| -> Option<String> {
            (m.len() > n && m[..n] == parent[..]).then(|| m[n].clone())
        };
        let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for (a, b) in &reach {
            if let (Some(x), Some(y)) = (child(a), child(b)) {
                if x != y {
                    edges.entry(x).or_default().insert(y);
                }
            }
        }
        if let Some(c) = cycle(&edges) {
            let under = if parent.is_empty() {
                "the crate root".to_string()
            } else {
                parent.join("::")
            };
            found.push(format!(
                "{}: under {under}: {}",
                root.display(),
                c.join(" -> ")
            ));
        }
    }
    found
}

#[test]
fn no_crate_has_an_import_cycle() {
    let top = Path::new(env!("CARGO_MANIFEST_DIR"));
    let found: Vec<String> = CRATES.iter().flat_map(|c| cycles(&top.join(c))).collect();
    assert!(found.is_empty(), "import cycles:\n{}", found.join("\n"));
}

/// The checker sees a cycle when there is one, through `use` trees, `super::` and paths
/// in code, and not through comments or tests.
#[test]
fn the_checker_finds_a_cycle_and_only_a_real_one() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path();
    std::fs::create_dir_all(src.join("b")).unwrap();
    let write = |p: &str, t: &str| std::fs::write(src.join(p), t).unwrap();
    write("lib.rs", "mod a;\nmod b;\nmod c;\n");
    write("a.rs", "use crate::{b::x::{Y, Z}};\n");
    write("b/mod.rs", "mod x;\n");
    write("b/x.rs", "fn f() { crate::c::g(); }\n");
    write(
        "c.rs",
        "// crate::a::h\n#[cfg(test)]\nmod tests { use crate::a; }\n",
    );
    assert!(cycles(src).is_empty());
    write("c.rs", "pub fn g() { let _ = crate::a::h; }\n");
    let found = cycles(src);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].contains("a -> b -> c -> a"), "{found:?}");
    write("c.rs", "");
    write("b/x.rs", "use super::super::a::Q;\n");
    let found = cycles(src);
    assert!(found[0].contains("a -> b -> a"), "{found:?}");
}

/// A cycle written through a re-export (the root's `pub use`, or an inline module's
/// such as `stages`) is a cycle; code after a test module, and test code however it is
/// written (a test module in a file of its own, a test function), are told apart.
#[test]
fn the_checker_sees_through_re_exports_and_around_test_code() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path();
    let write = |p: &str, t: &str| std::fs::write(src.join(p), t).unwrap();
    write(
        "lib.rs",
        "mod geom;\nmod reconstruct;\nmod field;\npub use reconstruct::{Params, run as go};\n\
         pub mod stages {\n    pub use crate::field::Prepared;\n}\n",
    );
    write(
        "reconstruct.rs",
        "use crate::geom::Point;\npub struct Params;\n",
    );
    write("field.rs", "pub struct Prepared;\n");
    write("geom.rs", "pub type Point = [f64; 2];\n");
    assert!(cycles(src).is_empty());
    // geom -> reconstruct through the root's re-export.
    write(
        "geom.rs",
        "use crate::Params;\npub type Point = [f64; 2];\n",
    );
    let found = cycles(src);
    assert!(
        found
            .iter()
            .any(|f| f.contains("geom -> reconstruct -> geom")),
        "{found:?}"
    );
    // ... and through an alias.
    write("geom.rs", "pub fn f() { crate::go(); }\n");
    let found = cycles(src);
    assert!(
        found
            .iter()
            .any(|f| f.contains("geom -> reconstruct -> geom")),
        "{found:?}"
    );
    // field -> geom, geom -> field through the inline module's re-export.
    write(
        "field.rs",
        "use crate::geom::Point;\npub struct Prepared;\n",
    );
    write("geom.rs", "use crate::stages::Prepared;\n");
    let found = cycles(src);
    assert!(
        found.iter().any(|f| f.contains("field -> geom -> field")),
        "{found:?}"
    );
    // Code after a test module counts; test code, in any form, does not.
    write(
        "geom.rs",
        "#[cfg(test)]\nmod tests {\n    use crate::Params;\n}\n#[cfg(test)]\nmod props;\n\
         #[cfg(test)]\nfn helper() { crate::stages::Prepared; }\npub fn after() {}\n",
    );
    write("props.rs", "use crate::Params;\n");
    std::fs::create_dir_all(src.join("geom")).unwrap();
    std::fs::rename(src.join("props.rs"), src.join("geom/props.rs")).unwrap();
    assert!(cycles(src).is_empty(), "{:?}", cycles(src));
    write(
        "geom.rs",
        "#[cfg(test)]\nmod tests {\n    fn t() {}\n}\npub fn after() { let _ = crate::Params; }\n",
    );
    let found = cycles(src);
    assert!(
        found
            .iter()
            .any(|f| f.contains("geom -> reconstruct -> geom")),
        "{found:?}"
    );
}
