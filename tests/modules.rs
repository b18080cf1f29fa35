//! How the sources are cut: no module cycle at any depth, and glob imports only where they belong.
//!
//! A module that uses a sibling which uses it back cannot be read, tested or moved alone. Paths are resolved
//! as the compiler would, closely enough for the project's own code: `crate::`, `super::`, `self::` and a
//! child module's name, through the `use` declarations of each module on the way (so `super::Prepared`
//! counts as the module that defines `Prepared`, wherever the parent re-exports it from). Test modules
//! (`tests`, and every item marked `#[cfg(test)]`) are left out: a test of a module uses it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The source directories of every crate of the workspace and of xtask.
fn source_dirs() -> Vec<PathBuf> {
    let crates = std::fs::read_dir(root().join("crates")).expect("crates/").flatten().map(|e| e.path().join("src"));
    crates.chain([root().join("xtask/src")]).filter(|p| p.is_dir()).collect()
}

/// A module's path within its crate (`["pipeline", "run_dir"]`; the crate root is empty).
type ModPath = Vec<String>;

/// One module's code without comments and tests, and what it names.
#[derive(Debug, Default)]
struct Module {
    code: String,
    /// Items defined at its top level.
    defs: BTreeSet<String>,
    /// `use` declarations: the name each brings in and the path it names.
    imports: BTreeMap<String, Vec<String>>,
    /// Glob imports (`use a::b::*;`): the paths before the `*`.
    globs: Vec<Vec<String>>,
    /// Its child modules (`mod x;` or a file `x.rs` / `x/mod.rs` beside it).
    children: BTreeSet<String>,
}

/// The module path of a source file relative to `src`, `None` for a test module.
fn module_path(rel: &Path) -> Option<ModPath> {
    let mut parts: Vec<String> = rel.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
    let file = parts.pop()?.strip_suffix(".rs")?.to_string();
    let crate_root = parts.is_empty() && (file == "lib" || file == "main");
    if !crate_root && file != "mod" {
        parts.push(file);
    }
    (!parts.iter().any(|p| p == "tests")).then_some(parts)
}

/// The code of a file that is not a comment or a test: an item after `#[cfg(test)]` (a `mod tests;` line, or
/// a block to its closing brace) is left out.
fn code_of(text: &str) -> String {
    let mut out = String::new();
    let (mut skipping, mut depth, mut opened) = (false, 0i64, false);
    for line in text.lines() {
        let t = line.trim_start();
        if t.starts_with("//") {
            continue;
        }
        if t.starts_with("#[cfg(test)]") {
            (skipping, depth, opened) = (true, 0, false);
            continue;
        }
        if skipping {
            depth += t.matches('{').count() as i64 - t.matches('}').count() as i64;
            opened |= t.contains('{');
            if (opened && depth <= 0) || (!opened && t.ends_with(';')) {
                skipping = false;
            }
            continue;
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

fn ident(s: &str) -> String {
    s.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect()
}

/// The paths of a `use` tree (`a::{b, c::{D, E as F}, g::*}`): (name brought in, path), `*` for a glob.
fn expand_use(prefix: &[String], tree: &str, out: &mut Vec<(String, Vec<String>)>) {
    let tree = tree.trim();
    if let Some(open) = tree.find('{') {
        let mut base = prefix.to_vec();
        base.extend(tree[..open].split("::").map(str::trim).filter(|s| !s.is_empty()).map(String::from));
        let inner = &tree[open + 1..tree.rfind('}').unwrap_or(tree.len())];
        let (mut depth, mut start) = (0, 0);
        for (i, c) in inner.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    expand_use(&base, &inner[start..i], out);
                    start = i + 1;
                }
                _ => {}
            }
        }
        expand_use(&base, &inner[start..], out);
        return;
    }
    if tree.is_empty() {
        return;
    }
    let (path, alias) = match tree.split_once(" as ") {
        Some((p, a)) => (p, Some(a.trim())),
        None => (tree, None),
    };
    let mut full = prefix.to_vec();
    full.extend(path.split("::").map(str::trim).filter(|s| !s.is_empty()).map(String::from));
    let name = alias.map(String::from).unwrap_or_else(|| full.last().cloned().unwrap_or_default());
    if name == "self" {
        full.pop();
        let name = full.last().cloned().unwrap_or_default();
        out.push((name, full));
    } else {
        out.push((name, full));
    }
}

/// Every module of the crate whose sources are in `src`.
fn modules_of(src: &Path) -> BTreeMap<ModPath, Module> {
    let mut modules: BTreeMap<ModPath, Module> = BTreeMap::new();
    let mut stack = vec![src.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).expect("readable").flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            let Some(m) = path.strip_prefix(src).ok().and_then(module_path) else { continue };
            let code = code_of(&std::fs::read_to_string(&path).expect("readable"));
            let module = modules.entry(m).or_default();
            module.code.push_str(&code);
        }
    }
    let paths: Vec<ModPath> = modules.keys().cloned().collect();
    for p in &paths {
        if let Some((last, parent)) = p.split_last()
            && let Some(m) = modules.get_mut(parent)
        {
            m.children.insert(last.clone());
        }
    }
    for m in modules.values_mut() {
        let mut statement = String::new();
        for line in m.code.lines() {
            let top = !line.starts_with(' ') && !line.starts_with('\t');
            let words: Vec<&str> = line.split_whitespace().collect();
            let is_use = words
                .iter()
                .position(|w| *w == "use")
                .is_some_and(|i| words[..i].iter().all(|w| w.starts_with("pub") || w.starts_with("#[")));
            if top && (is_use || !statement.is_empty()) {
                statement.push_str(line);
                statement.push(' ');
                if line.trim_end().ends_with(';') {
                    let tree = statement.split_once("use ").map(|(_, t)| t).unwrap_or("");
                    let mut out = Vec::new();
                    expand_use(&[], tree.trim().trim_end_matches(';'), &mut out);
                    for (name, path) in out {
                        if name == "*" {
                            m.globs.push(path[..path.len() - 1].to_vec());
                        } else {
                            m.imports.insert(name, path);
                        }
                    }
                    statement.clear();
                }
                continue;
            }
            if top {
                let rest = words.iter().skip_while(|w| w.starts_with("pub") || w.starts_with("#[")).collect::<Vec<_>>();
                if let [kind, name, ..] = rest.as_slice() {
                    let kind = kind.trim_start_matches("unsafe");
                    if ["struct", "enum", "fn", "const", "static", "type", "trait", "mod", "union"].contains(&kind)
                        || kind == "macro_rules!"
                    {
                        m.defs.insert(ident(name));
                    }
                }
            }
        }
    }
    modules
}

/// The module that `path`, written in module `at`, names (the deepest module on its way).
fn resolve(modules: &BTreeMap<ModPath, Module>, at: &[String], path: &[String], depth: usize) -> Option<ModPath> {
    if depth > 16 || path.is_empty() {
        return None;
    }
    let mut cur: ModPath;
    let mut rest = path;
    match path[0].as_str() {
        "crate" => {
            cur = Vec::new();
            rest = &path[1..];
        }
        "self" => {
            cur = at.to_vec();
            rest = &path[1..];
        }
        "super" => {
            cur = at.to_vec();
            while rest.first().is_some_and(|s| s == "super") {
                cur.pop()?;
                rest = &rest[1..];
            }
        }
        first => {
            let here = modules.get(at)?;
            if here.children.contains(first) {
                cur = at.to_vec();
            } else if let Some(full) = here.imports.get(first) {
                if full.first().is_some_and(|s| s == first) && full.len() == 1 {
                    return None;
                }
                let mut p = full.clone();
                p.extend(path[1..].iter().cloned());
                return resolve(modules, at, &p, depth + 1);
            } else {
                return None;
            }
        }
    }
    for seg in rest {
        let module = modules.get(&cur)?;
        if module.children.contains(seg) {
            cur.push(seg.clone());
        } else if let Some(full) = module.imports.get(seg) {
            return resolve(modules, &cur, full, depth + 1).or(Some(cur));
        } else if !module.defs.contains(seg) {
            for glob in &module.globs {
                if let Some(g) = resolve(modules, &cur, glob, depth + 1)
                    && modules.get(&g).is_some_and(|m| m.defs.contains(seg) || m.imports.contains_key(seg))
                {
                    let mut p = glob.clone();
                    p.push(seg.clone());
                    return resolve(modules, &cur, &p, depth + 1).or(Some(g));
                }
            }
            return Some(cur);
        } else {
            return Some(cur);
        }
    }
    Some(cur)
}

/// The paths a module's code names: `crate::`, `super::` and `self::` paths, paths through its child
/// modules, and its `use` declarations.
fn references(m: &Module) -> Vec<Vec<String>> {
    let mut out: Vec<Vec<String>> = m.imports.values().cloned().collect();
    out.extend(m.globs.iter().cloned());
    let code = &m.code;
    let bytes = code.as_bytes();
    let mut i = 0;
    while i < code.len() {
        let starts_word =
            i == 0 || !(bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_' || bytes[i - 1] == b':');
        let word = ident(&code[i..]);
        if !starts_word || word.is_empty() {
            i += code[i..].chars().next().map_or(1, char::len_utf8);
            continue;
        }
        let mut path = vec![word.clone()];
        let mut j = i + word.len();
        while code[j..].starts_with("::") {
            let next = ident(&code[j + 2..]);
            if next.is_empty() {
                break;
            }
            j += 2 + next.len();
            path.push(next);
        }
        if path.len() > 1 && (["crate", "super", "self"].contains(&path[0].as_str()) || m.children.contains(&path[0])) {
            out.push(path);
        }
        i = j.max(i + 1);
    }
    out
}

/// The cycles among the children of each module, as "a → b → a" lines.
fn cycles_in(modules: &BTreeMap<ModPath, Module>) -> Vec<String> {
    // Edges between siblings: module `from` (or a module below it) names `to` (or a module below it).
    let mut edges: BTreeMap<ModPath, BTreeSet<ModPath>> = BTreeMap::new();
    for (at, m) in modules {
        for path in references(m) {
            let Some(target) = resolve(modules, at, &path, 0) else { continue };
            let common = at.iter().zip(&target).take_while(|(a, b)| a == b).count();
            if common < at.len() && common < target.len() {
                edges.entry(at[..=common].to_vec()).or_default().insert(target[..=common].to_vec());
            }
        }
    }
    let mut found = Vec::new();
    for start in edges.keys() {
        let mut stack = vec![vec![start.clone()]];
        let mut seen = BTreeSet::new();
        while let Some(path) = stack.pop() {
            let last = path.last().expect("non-empty");
            for next in edges.get(last).into_iter().flatten() {
                if next == start {
                    let names: Vec<String> = path.iter().chain([start]).map(|p| p.join("::")).collect();
                    found.push(names.join(" → "));
                } else if seen.insert(next.clone()) {
                    stack.push([path.clone(), vec![next.clone()]].concat());
                }
            }
        }
    }
    found
}

/// No module of any crate is part of a cycle among its siblings, at any depth (`pipeline::run_dir` calling
/// `pipeline::choose`, which takes its file names back from `run_dir`, was one).
#[test]
fn no_module_cycle_at_any_depth() {
    let mut cycles = Vec::new();
    for src in source_dirs() {
        let rel = src.strip_prefix(root()).unwrap_or(&src).display().to_string();
        cycles.extend(cycles_in(&modules_of(&src)).into_iter().map(|c| format!("{rel}: {c}")));
    }
    assert!(cycles.is_empty(), "module cycles:\n{}", cycles.join("\n"));
}

/// The detector finds a cycle between siblings through a parent's re-export, one between modules two levels
/// apart, and none where a child uses its parent's own items.
#[test]
fn the_cycle_detector_detects() {
    let dir = std::env::temp_dir().join(format!("nlos-modules-{}", std::process::id()));
    let files: &[(&str, &str)] = &[
        ("lib.rs", "mod a;\nmod b;\npub use a::Shared;\n"),
        ("a/mod.rs", "mod run;\nmod choose;\npub struct Shared;\npub use run::FILE;\n"),
        ("a/run.rs", "use super::choose;\npub const FILE: &str = \"x\";\npub fn go() { choose::pick(); }\n"),
        ("a/choose.rs", "use super::FILE;\npub fn pick() { let _ = FILE; }\n"),
        ("b.rs", "pub fn f() { let _ = crate::Shared; }\n"),
    ];
    for (name, text) in files {
        let path = dir.join(name);
        std::fs::create_dir_all(path.parent().expect("parent")).expect("dir");
        std::fs::write(&path, text).expect("write");
    }
    let cycles = cycles_in(&modules_of(&dir));
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(cycles.len(), 2, "{cycles:?}");
    assert!(cycles.iter().all(|c| c.contains("a::run") && c.contains("a::choose")), "{cycles:?}");
}

/// Whether a module's code is a flat list of re-exports: nothing but `mod` and `use` declarations.
fn only_reexports(code: &str) -> bool {
    code.lines().map(str::trim).filter(|l| !l.is_empty() && !l.starts_with("#[") && !l.starts_with("#![")).all(|l| {
        let l = l.trim_start_matches("pub(crate) ").trim_start_matches("pub(super) ").trim_start_matches("pub ");
        l.starts_with("mod ") || l.starts_with("use ") || l.starts_with('}') || !l.contains(['(', '=', '{'])
    })
}

/// Glob imports (`use x::*`) only in test modules, of a crate's prelude, or where a module is a flat list of
/// re-exports: elsewhere a reader cannot tell where a name comes from.
#[test]
fn glob_imports_only_where_they_belong() {
    let mut found = Vec::new();
    for src in source_dirs() {
        for (path, m) in modules_of(&src) {
            if only_reexports(&m.code) {
                continue;
            }
            for glob in m.globs.iter().filter(|g| g.last().is_none_or(|s| s != "prelude")) {
                let rel = src.strip_prefix(root()).unwrap_or(&src).display();
                found.push(format!("{rel}: {}: use {}::*", path.join("::"), glob.join("::")));
            }
        }
    }
    assert!(found.is_empty(), "glob imports outside tests and re-export lists:\n{}", found.join("\n"));
}
