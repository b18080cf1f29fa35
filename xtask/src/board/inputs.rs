//! What a row of the board ran on: its inputs as named components, each with a digest, so that a row is stale
//! only when something it ran can have changed.
//!
//! A component is a name and the first 12 hex digits of a SHA-256:
//! - `code PKG` — the Rust source of the workspace crates in PKG's dependency closure (normal and build
//!   dependencies: what the built binary holds), followed through the module tree of each library and binary
//!   target ([`module_files`]) as tokens without comments, doc comments, lint attributes and `#[cfg(test)]`
//!   items ([`normalized`]), so that none of those, nor a test, a benchmark or a document, changes it; the
//!   files the source includes (`include_str!`); the resolved third-party packages with their features; the
//!   release profile and the build configuration. nlos-transient's capture readers are left out: each is a
//!   component of its own.
//! - `reader NAME` — one reader module of `crates/nlos-transient/src/formats` (`mat`, `hdf5`, `npy`, …), the
//!   same tokens. A row depends on the readers of the files it reads and on the readers those refer to
//!   ([`Fingerprints::reader_closure`]).
//! - `scenario NAME` — the xtask sources that define the scenario ([`super::scenario_sources`]).
//! - `fuzz TARGET` — the fuzz target's source and the fuzz crate's manifest and lock file.
//! - `data NAME` — the shared files the scenario reads ([`super::scenario_data`]), names and contents.
//!
//! A section of `docs/results.md` lists its components on its `inputs:` line ([`Inputs`]); `cargo xtask
//! status` recomputes each and names those that differ.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::str::FromStr;

use proc_macro2::{Delimiter, Group, TokenStream, TokenTree};
use sha2::{Digest, Sha256};

/// The directory of nlos-transient's capture readers: each child module is a `reader` component.
const READERS_DIR: &str = "crates/nlos-transient/src/formats";

/// Hex digits of a component's digest kept on the board.
const DIGITS: usize = 12;

fn digest(bytes: &[u8]) -> String {
    let d = Sha256::digest(bytes);
    d.iter().map(|b| format!("{b:02x}")).collect::<String>()[..DIGITS].to_string()
}

/// The inputs line of a section: component name → digest, in name order.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct Inputs(pub(crate) BTreeMap<String, String>);

pub(crate) const INPUTS_LINE: &str = "inputs: ";

impl Inputs {
    /// `inputs: code nlos-cli `…` · reader hdf5 `…` · …`.
    pub(crate) fn line(&self) -> String {
        let parts: Vec<String> = self.0.iter().map(|(k, v)| format!("{k} `{v}`")).collect();
        format!("{INPUTS_LINE}{}", parts.join(" · "))
    }

    /// The inputs line of a section body, None when it has none.
    pub(crate) fn parse(body: &str) -> Option<Self> {
        let line = body.lines().find_map(|l| l.strip_prefix(INPUTS_LINE))?;
        let mut map = BTreeMap::new();
        for part in line.split(" · ") {
            let (name, rest) = part.split_once(" `")?;
            map.insert(name.to_string(), rest.trim_end_matches('`').to_string());
        }
        Some(Self(map))
    }
}

/// How an attribute bears on what the code computes.
enum Attr {
    /// It changes nothing the binary does: a doc comment, a lint level, a tool attribute.
    Inert,
    /// The item it is on exists only in tests.
    TestOnly,
    Keep,
}

fn attribute_kind(stream: &TokenStream) -> Attr {
    let tokens: Vec<TokenTree> = stream.clone().into_iter().collect();
    let Some(TokenTree::Ident(name)) = tokens.first() else { return Attr::Keep };
    let name = name.to_string();
    let args = match tokens.get(1) {
        Some(TokenTree::Group(g)) if g.delimiter() == Delimiter::Parenthesis => Some(g.stream().to_string()),
        _ => None,
    };
    let lint = |n: &str| ["doc", "allow", "expect", "warn", "deny", "forbid", "must_use"].contains(&n);
    // A path attribute such as `#[rustfmt::skip]` or `#[clippy::…]`.
    let tool = matches!(tokens.get(1), Some(TokenTree::Punct(p)) if p.as_char() == ':')
        && ["rustfmt", "clippy", "diagnostic"].contains(&name.as_str());
    match (name.as_str(), args.as_deref()) {
        (n, _) if lint(n) || tool => Attr::Inert,
        ("cfg", Some("test")) => Attr::TestOnly,
        // `#[cfg_attr(PRED, A, B)]` with every attribute inert.
        ("cfg_attr", Some(_)) => {
            let Some(TokenTree::Group(g)) = tokens.get(1) else { return Attr::Keep };
            let parts = split_commas(g.stream());
            let inert = parts.len() > 1
                && parts[1..].iter().all(|p| matches!(attribute_kind(p), Attr::Inert))
                && !parts[1..].is_empty();
            if inert { Attr::Inert } else { Attr::Keep }
        }
        _ => Attr::Keep,
    }
}

fn split_commas(stream: TokenStream) -> Vec<TokenStream> {
    let mut parts = vec![Vec::new()];
    for t in stream {
        match &t {
            TokenTree::Punct(p) if p.as_char() == ',' => parts.push(Vec::new()),
            _ => parts.last_mut().expect("one part at least").push(t),
        }
    }
    parts.into_iter().filter(|p| !p.is_empty()).map(|p| p.into_iter().collect()).collect()
}

/// Keywords an item can start with (after its attributes): where `#[cfg(test)]` removes a whole item.
const ITEM_START: [&str; 15] = [
    "pub",
    "fn",
    "mod",
    "use",
    "const",
    "static",
    "struct",
    "enum",
    "impl",
    "trait",
    "type",
    "unsafe",
    "extern",
    "async",
    "macro_rules",
];

fn is_attribute_at(tokens: &[TokenTree], i: usize) -> Option<usize> {
    let TokenTree::Punct(p) = tokens.get(i)? else { return None };
    if p.as_char() != '#' {
        return None;
    }
    let j = i + 1 + usize::from(matches!(tokens.get(i + 1), Some(TokenTree::Punct(q)) if q.as_char() == '!'));
    match tokens.get(j)? {
        TokenTree::Group(g) if g.delimiter() == Delimiter::Bracket => Some(j),
        _ => None,
    }
}

/// The index after the item that starts at `i` (after any further attributes): its first `;` or brace group
/// at this level. None when no item starts there (an attribute on a field, a statement or an arm).
fn item_end(tokens: &[TokenTree], mut i: usize) -> Option<usize> {
    while let Some(j) = is_attribute_at(tokens, i) {
        i = j + 1;
    }
    match tokens.get(i)? {
        TokenTree::Ident(id) if ITEM_START.contains(&id.to_string().as_str()) => {}
        _ => return None,
    }
    while let Some(t) = tokens.get(i) {
        match t {
            TokenTree::Punct(p) if p.as_char() == ';' => return Some(i + 1),
            TokenTree::Group(g) if g.delimiter() == Delimiter::Brace => return Some(i + 1),
            _ => i += 1,
        }
    }
    Some(i)
}

/// `stream` without inert attributes and test-only items, at every level.
fn strip(stream: TokenStream) -> TokenStream {
    let tokens: Vec<TokenTree> = stream.into_iter().collect();
    let mut out: Vec<TokenTree> = Vec::with_capacity(tokens.len());
    let mut i = 0;
    while i < tokens.len() {
        if let Some(j) = is_attribute_at(&tokens, i) {
            let TokenTree::Group(g) = &tokens[j] else { unreachable!("is_attribute_at checks the group") };
            let inner = j == i + 2;
            match attribute_kind(&g.stream()) {
                Attr::Inert => {
                    i = j + 1;
                    continue;
                }
                // `#![cfg(test)]`: the enclosing file or module is test code.
                Attr::TestOnly if inner => return TokenStream::new(),
                Attr::TestOnly => {
                    if let Some(end) = item_end(&tokens, j + 1) {
                        i = end;
                        continue;
                    }
                }
                Attr::Keep => {}
            }
        }
        out.push(match &tokens[i] {
            TokenTree::Group(g) => TokenTree::Group(Group::new(g.delimiter(), strip(g.stream()))),
            t => t.clone(),
        });
        i += 1;
    }
    out.into_iter().collect()
}

/// The tokens of Rust source `text` that what it compiles to depends on: comments, doc comments, lint and
/// tool attributes and `#[cfg(test)]` items removed; spacing and line breaks gone with the tokenisation.
pub(crate) fn normalized(text: &str) -> Result<TokenStream, String> {
    let stream = TokenStream::from_str(text).map_err(|e| format!("not Rust tokens: {e}"))?;
    Ok(strip(stream))
}

/// A source file of a module tree: its path (relative to the workspace root) and its normalised tokens.
struct Source {
    path: PathBuf,
    tokens: TokenStream,
}

/// Files a source includes: path and bytes.
type Included = Vec<(PathBuf, Vec<u8>)>;

/// The files of the module tree rooted at `entry` (a crate's `lib.rs`, `main.rs` or `build.rs`), test-only
/// modules left out, with the files their `include_str!`/`include_bytes!` name (as `(path, bytes)`).
fn module_files(root: &Path, entry: &Path) -> Result<(Vec<Source>, Included), String> {
    let mut sources = Vec::new();
    let mut included = Vec::new();
    let mut todo = vec![(entry.to_path_buf(), entry.parent().map(Path::to_path_buf).unwrap_or_default())];
    while let Some((file, dir)) = todo.pop() {
        let full = root.join(&file);
        let text = std::fs::read_to_string(&full).map_err(|e| format!("{}: {e}", full.display()))?;
        let tokens = normalized(&text).map_err(|e| format!("{}: {e}", full.display()))?;
        let base = file.parent().map(Path::to_path_buf).unwrap_or_default();
        collect_modules(&tokens, &dir, &mut todo, root)?;
        collect_includes(&tokens, &base, root, &mut included)?;
        sources.push(Source { path: file, tokens });
    }
    sources.sort_by(|a, b| a.path.cmp(&b.path));
    included.sort();
    Ok((sources, included))
}

/// `mod NAME;` declarations in `tokens` (inline `mod NAME { … }` descends into `dir/NAME`), queued as
/// `(file, its module directory)`.
fn collect_modules(
    tokens: &TokenStream,
    dir: &Path,
    todo: &mut Vec<(PathBuf, PathBuf)>,
    root: &Path,
) -> Result<(), String> {
    let t: Vec<TokenTree> = tokens.clone().into_iter().collect();
    for (i, tok) in t.iter().enumerate() {
        let TokenTree::Ident(kw) = tok else {
            if let TokenTree::Group(g) = tok {
                let inline_mod = i >= 2
                    && matches!(&t[i - 2], TokenTree::Ident(k) if *k == "mod")
                    && g.delimiter() == Delimiter::Brace;
                let sub = match (&t.get(i.wrapping_sub(1)), inline_mod) {
                    (Some(TokenTree::Ident(name)), true) => dir.join(name.to_string()),
                    _ => dir.to_path_buf(),
                };
                collect_modules(&g.stream(), &sub, todo, root)?;
            }
            continue;
        };
        if *kw != "mod" {
            continue;
        }
        let (Some(TokenTree::Ident(name)), Some(TokenTree::Punct(semi))) = (t.get(i + 1), t.get(i + 2)) else {
            continue;
        };
        if semi.as_char() != ';' {
            continue;
        }
        let name = name.to_string();
        let flat = dir.join(format!("{name}.rs"));
        let nested = dir.join(&name).join("mod.rs");
        let file = if root.join(&flat).exists() { flat } else { nested };
        if !root.join(&file).exists() {
            return Err(format!("module `{name}` declared in {} has no file", dir.display()));
        }
        todo.push((file, dir.join(&name)));
    }
    Ok(())
}

/// Files named by `include_str!("…")` / `include_bytes!("…")` in `tokens`, relative to `base`.
fn collect_includes(
    tokens: &TokenStream,
    base: &Path,
    root: &Path,
    out: &mut Vec<(PathBuf, Vec<u8>)>,
) -> Result<(), String> {
    let t: Vec<TokenTree> = tokens.clone().into_iter().collect();
    for (i, tok) in t.iter().enumerate() {
        match tok {
            TokenTree::Group(g) => collect_includes(&g.stream(), base, root, out)?,
            TokenTree::Ident(id) if *id == "include_str" || *id == "include_bytes" => {
                let Some(TokenTree::Group(g)) = t.get(i + 2) else { continue };
                let lit = g.stream().to_string();
                let Some(name) = lit.strip_prefix('"').and_then(|l| l.strip_suffix('"')) else {
                    return Err(format!("{}: an include of `{lit}`, not a plain path", base.display()));
                };
                let path = base.join(name);
                let bytes = std::fs::read(root.join(&path)).map_err(|e| format!("{}: {e}", path.display()))?;
                out.push((path, bytes));
            }
            _ => {}
        }
    }
    Ok(())
}

/// The reader a source file belongs to: the child module of [`READERS_DIR`] it lies in.
fn reader_of(path: &Path) -> Option<String> {
    let rest = path.strip_prefix(READERS_DIR).ok()?;
    let first = rest.components().next()?.as_os_str().to_string_lossy().into_owned();
    if first == "mod.rs" {
        return None;
    }
    Some(first.trim_end_matches(".rs").to_string())
}

/// Identifiers that sit next to a `::` anywhere in `tokens` (path segments).
fn path_segments(tokens: &TokenStream, out: &mut BTreeSet<String>) {
    let t: Vec<TokenTree> = tokens.clone().into_iter().collect();
    let colon = |k: usize| matches!(t.get(k), Some(TokenTree::Punct(p)) if p.as_char() == ':');
    for (i, tok) in t.iter().enumerate() {
        match tok {
            TokenTree::Group(g) => path_segments(&g.stream(), out),
            TokenTree::Ident(id) if (colon(i + 1) && colon(i + 2)) || (i >= 2 && colon(i - 1) && colon(i - 2)) => {
                out.insert(id.to_string());
            }
            _ => {}
        }
    }
}

/// The package graph of `cargo metadata`.
struct Meta {
    /// Package id → (name, version, source, manifest directory relative to the root or None when outside).
    packages: HashMap<String, (String, String, String, Option<PathBuf>)>,
    /// Package id → its targets' (kinds, source path relative to the root).
    targets: HashMap<String, Vec<(Vec<String>, PathBuf)>>,
    /// Package id → (normal and build dependency ids, enabled features).
    nodes: HashMap<String, (Vec<String>, Vec<String>)>,
    by_name: HashMap<String, String>,
}

impl Meta {
    fn load(root: &Path) -> Result<Self, String> {
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let out = Command::new(cargo)
            .current_dir(root)
            .args(["metadata", "--format-version", "1", "--locked"])
            .output()
            .map_err(|e| format!("cannot run cargo metadata: {e}"))?;
        if !out.status.success() {
            return Err(format!("cargo metadata failed: {}", String::from_utf8_lossy(&out.stderr).trim()));
        }
        let v: serde_json::Value =
            serde_json::from_slice(&out.stdout).map_err(|e| format!("cargo metadata output: {e}"))?;
        let root_abs = root.canonicalize().unwrap_or_else(|_| root.to_path_buf());
        let rel = |p: &str| Path::new(p).strip_prefix(&root_abs).ok().map(Path::to_path_buf);
        let str_of = |x: &serde_json::Value| x.as_str().unwrap_or_default().to_string();
        let mut meta =
            Self { packages: HashMap::new(), targets: HashMap::new(), nodes: HashMap::new(), by_name: HashMap::new() };
        for p in v["packages"].as_array().into_iter().flatten() {
            let id = str_of(&p["id"]);
            let dir =
                rel(p["manifest_path"].as_str().unwrap_or_default()).and_then(|m| m.parent().map(Path::to_path_buf));
            let targets = p["targets"]
                .as_array()
                .into_iter()
                .flatten()
                .map(|t| {
                    let kinds = t["kind"].as_array().into_iter().flatten().map(str_of).collect();
                    (kinds, rel(t["src_path"].as_str().unwrap_or_default()).unwrap_or_default())
                })
                .collect();
            meta.targets.insert(id.clone(), targets);
            if dir.is_some() {
                meta.by_name.insert(str_of(&p["name"]), id.clone());
            }
            meta.packages.insert(id, (str_of(&p["name"]), str_of(&p["version"]), str_of(&p["source"]), dir));
        }
        for n in v["resolve"]["nodes"].as_array().into_iter().flatten() {
            let deps = n["deps"]
                .as_array()
                .into_iter()
                .flatten()
                .filter(|d| {
                    d["dep_kinds"].as_array().into_iter().flatten().any(|k| k["kind"].is_null() || k["kind"] == "build")
                })
                .map(|d| str_of(&d["pkg"]))
                .collect();
            let features = n["features"].as_array().into_iter().flatten().map(str_of).collect();
            meta.nodes.insert(str_of(&n["id"]), (deps, features));
        }
        Ok(meta)
    }

    /// The ids of the packages `names` and everything they depend on (normal and build dependencies).
    fn closure(&self, names: &[&str]) -> Result<BTreeSet<String>, String> {
        let mut seen = BTreeSet::new();
        let mut todo = Vec::new();
        for n in names {
            todo.push(self.by_name.get(*n).cloned().ok_or_else(|| format!("no workspace package `{n}`"))?);
        }
        while let Some(id) = todo.pop() {
            if seen.insert(id.clone())
                && let Some((deps, _)) = self.nodes.get(&id)
            {
                todo.extend(deps.iter().cloned());
            }
        }
        Ok(seen)
    }
}

/// Computes components, each once per process.
pub(crate) struct Fingerprints {
    root: PathBuf,
    meta: Option<Result<Meta, String>>,
    memo: HashMap<String, Result<String, String>>,
    /// Reader name → its files' tokens, from the walk of nlos-transient.
    readers: Option<Result<BTreeMap<String, Vec<Source>>, String>>,
}

impl std::fmt::Debug for Fingerprints {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Fingerprints").field("root", &self.root).finish_non_exhaustive()
    }
}

impl Fingerprints {
    pub(crate) fn new(root: &Path) -> Self {
        Self { root: root.to_path_buf(), meta: None, memo: HashMap::new(), readers: None }
    }

    fn meta(&mut self) -> Result<&Meta, String> {
        if self.meta.is_none() {
            self.meta = Some(Meta::load(&self.root));
        }
        self.meta.as_ref().expect("just set").as_ref().map_err(Clone::clone)
    }

    /// The digest of component `name` (`code PKG[+PKG…]`, `reader NAME`, `scenario NAME`, `fuzz TARGET`,
    /// `data NAME`) as the working tree and the shared data are now.
    pub(crate) fn component(&mut self, name: &str) -> Result<String, String> {
        if let Some(v) = self.memo.get(name) {
            return v.clone();
        }
        let v = match name.split_once(' ') {
            Some(("code", pkgs)) => self.code(&pkgs.split('+').collect::<Vec<_>>()),
            Some(("reader", r)) => self.reader(r),
            Some(("scenario", s)) => self.scenario(s),
            Some(("fuzz", t)) => self.fuzz_target(t),
            Some(("data", s)) => self.data(s),
            _ => Err(format!("unknown component `{name}`")),
        };
        self.memo.insert(name.to_string(), v.clone());
        v
    }

    /// `code PKGS`: see the module docs.
    fn code(&mut self, pkgs: &[&str]) -> Result<String, String> {
        let root = self.root.clone();
        let meta = self.meta()?;
        let ids = meta.closure(pkgs)?;
        let mut h = Sha256::new();
        for id in &ids {
            let (name, version, source, dir) = &meta.packages[id];
            let features = meta.nodes.get(id).map(|n| n.1.join(",")).unwrap_or_default();
            h.update(format!("package {name} {version} {source} [{features}]\n"));
            if dir.is_none() {
                continue;
            }
            let is_root = pkgs.contains(&name.as_str());
            for (kinds, src) in &meta.targets[id] {
                let wanted = kinds.iter().any(|k| {
                    matches!(k.as_str(), "lib" | "rlib" | "proc-macro" | "custom-build" | "cdylib")
                        || (is_root && k == "bin")
                });
                if !wanted {
                    continue;
                }
                let (sources, included) = module_files(&root, src)?;
                for s in sources.iter().filter(|s| reader_of(&s.path).is_none()) {
                    h.update(format!("file {}\n{}\n", s.path.display(), s.tokens));
                }
                for (path, bytes) in included {
                    h.update(format!("include {} {}\n", path.display(), bytes.len()));
                    h.update(&bytes);
                }
            }
        }
        // What the build does with the source: the release profile and the build configuration.
        let manifest = std::fs::read_to_string(root.join("Cargo.toml")).map_err(|e| format!("Cargo.toml: {e}"))?;
        let manifest: toml::Table = manifest.parse().map_err(|e| format!("Cargo.toml: {e}"))?;
        h.update(format!("profile {:?}\n", manifest.get("profile").and_then(|p| p.get("release"))));
        if let Ok(config) = std::fs::read_to_string(root.join(".cargo/config.toml")) {
            let config: toml::Table = config.parse().map_err(|e| format!(".cargo/config.toml: {e}"))?;
            for key in ["build", "target", "profile"] {
                h.update(format!("config {key} {:?}\n", config.get(key)));
            }
        }
        Ok(digest(&h.finalize()))
    }

    fn readers(&mut self) -> Result<&BTreeMap<String, Vec<Source>>, String> {
        if self.readers.is_none() {
            let lib = PathBuf::from("crates/nlos-transient/src/lib.rs");
            let walked = module_files(&self.root, &lib).map(|(sources, _)| {
                let mut by: BTreeMap<String, Vec<Source>> = BTreeMap::new();
                for s in sources {
                    if let Some(r) = reader_of(&s.path) {
                        by.entry(r).or_default().push(s);
                    }
                }
                by
            });
            self.readers = Some(walked);
        }
        self.readers.as_ref().expect("just set").as_ref().map_err(Clone::clone)
    }

    fn reader(&mut self, name: &str) -> Result<String, String> {
        let files = self.readers()?.get(name).ok_or_else(|| format!("no reader `{name}` in {READERS_DIR}"))?;
        let mut h = Sha256::new();
        for s in files {
            h.update(format!("file {}\n{}\n", s.path.display(), s.tokens));
        }
        Ok(digest(&h.finalize()))
    }

    /// The readers `entries` reach: themselves and, transitively, every reader whose module name their
    /// source uses as a path segment (`super::npy::…`, `crate::formats::mat::…`).
    pub(crate) fn reader_closure(&mut self, entries: &BTreeSet<String>) -> Result<BTreeSet<String>, String> {
        let readers = self.readers()?;
        let names: BTreeSet<String> = readers.keys().cloned().collect();
        let mut seen = BTreeSet::new();
        let mut todo: Vec<String> = entries.iter().filter(|e| names.contains(*e)).cloned().collect();
        while let Some(r) = todo.pop() {
            if !seen.insert(r.clone()) {
                continue;
            }
            let mut segs = BTreeSet::new();
            for s in &readers[&r] {
                path_segments(&s.tokens, &mut segs);
            }
            todo.extend(segs.intersection(&names).filter(|n| **n != r).cloned());
        }
        Ok(seen)
    }

    fn scenario(&mut self, name: &str) -> Result<String, String> {
        let mut h = Sha256::new();
        for file in super::scenario_sources(name) {
            let path = PathBuf::from("xtask/src").join(file);
            let text =
                std::fs::read_to_string(self.root.join(&path)).map_err(|e| format!("{}: {e}", path.display()))?;
            let tokens = normalized(&text).map_err(|e| format!("{}: {e}", path.display()))?;
            h.update(format!("file {}\n{tokens}\n", path.display()));
        }
        Ok(digest(&h.finalize()))
    }

    fn fuzz_target(&mut self, target: &str) -> Result<String, String> {
        let entry = PathBuf::from("fuzz/fuzz_targets").join(format!("{target}.rs"));
        let (sources, included) = module_files(&self.root, &entry)?;
        let mut h = Sha256::new();
        for s in &sources {
            h.update(format!("file {}\n{}\n", s.path.display(), s.tokens));
        }
        for (path, bytes) in included {
            h.update(format!("include {}\n", path.display()));
            h.update(&bytes);
        }
        for f in ["fuzz/Cargo.toml", "fuzz/Cargo.lock"] {
            h.update(std::fs::read(self.root.join(f)).map_err(|e| format!("{f}: {e}"))?);
        }
        Ok(digest(&h.finalize()))
    }

    /// The workspace crates a fuzz target's source names (`nlos_transient::…` → `nlos-transient`).
    pub(crate) fn fuzz_crates(&mut self, target: &str) -> Result<Vec<String>, String> {
        let entry = PathBuf::from("fuzz/fuzz_targets").join(format!("{target}.rs"));
        let (sources, _) = module_files(&self.root, &entry)?;
        let mut segs = BTreeSet::new();
        for s in &sources {
            path_segments(&s.tokens, &mut segs);
        }
        let crates: Vec<String> = segs.iter().filter(|s| s.starts_with("nlos_")).map(|s| s.replace('_', "-")).collect();
        if crates.is_empty() { Err(format!("{}: names no nlos crate", entry.display())) } else { Ok(crates) }
    }

    fn data(&mut self, name: &str) -> Result<String, String> {
        let shared = super::shared("");
        let mut files = Vec::new();
        for item in super::scenario_data(name) {
            let path = shared.join(item);
            if path.is_dir() {
                let mut stack = vec![path];
                while let Some(d) = stack.pop() {
                    for e in std::fs::read_dir(&d).map_err(|e| format!("{}: {e}", d.display()))?.flatten() {
                        if e.path().is_dir() { stack.push(e.path()) } else { files.push(e.path()) }
                    }
                }
            } else {
                files.push(path);
            }
        }
        files.sort();
        let mut h = Sha256::new();
        for f in files {
            let bytes = std::fs::read(&f).map_err(|e| format!("shared data {}: {e}", f.display()))?;
            let rel = f.strip_prefix(&shared).unwrap_or(&f);
            h.update(format!("file {} {}\n", rel.display(), bytes.len()));
            h.update(&bytes);
        }
        Ok(digest(&h.finalize()))
    }

    /// The components of a scenario's row: the `nlos` binary's code, the readers of the files it read (its
    /// shared data by their content, the files its commands name under `out/` by their extension), its
    /// definition and its data.
    pub(crate) fn scenario_inputs(&mut self, name: &str, commands: &[String]) -> Result<Inputs, String> {
        let mut entries = BTreeSet::new();
        let shared = super::shared("");
        for item in super::scenario_data(name) {
            let path = shared.join(item);
            let files: Vec<PathBuf> = if path.is_dir() {
                std::fs::read_dir(&path)
                    .map_err(|e| format!("{}: {e}", path.display()))?
                    .flatten()
                    .map(|e| e.path())
                    .collect()
            } else {
                vec![path]
            };
            for f in files {
                entries.extend(readers_of_file(&f));
            }
        }
        for c in commands {
            for arg in c.split_whitespace() {
                if arg.starts_with("out/") || arg.contains("/out/") {
                    entries.extend(readers_of_extension(Path::new(arg)));
                }
            }
        }
        let mut names = vec![format!("code {}", super::BINARY_PACKAGE)];
        names.extend(self.reader_closure(&entries)?.into_iter().map(|r| format!("reader {r}")));
        names.push(format!("scenario {name}"));
        if !super::scenario_data(name).is_empty() {
            names.push(format!("data {name}"));
        }
        self.components(&names)
    }

    /// The components of a fuzz target's row: its source, the code of the crates it names, the readers it
    /// enters (`entries`) and those they use.
    pub(crate) fn fuzz_inputs(&mut self, target: &str, entries: &[&str]) -> Result<Inputs, String> {
        let crates = self.fuzz_crates(target)?;
        let mut names = vec![format!("fuzz {target}"), format!("code {}", crates.join("+"))];
        let entries: BTreeSet<String> = entries.iter().map(|e| (*e).to_string()).collect();
        names.extend(self.reader_closure(&entries)?.into_iter().map(|r| format!("reader {r}")));
        self.components(&names)
    }

    fn components(&mut self, names: &[String]) -> Result<Inputs, String> {
        let mut map = BTreeMap::new();
        for n in names {
            map.insert(n.clone(), self.component(n)?);
        }
        Ok(Inputs(map))
    }

    /// Why `recorded` no longer describes the working tree: the components whose digest changed (or cannot be
    /// computed), None when every one is as recorded.
    pub(crate) fn changed(&mut self, recorded: &Inputs) -> Option<String> {
        let mut changed = Vec::new();
        for (name, digest) in &recorded.0 {
            match self.component(name) {
                Ok(now) if now == *digest => {}
                Ok(_) => changed.push(name.clone()),
                Err(e) => changed.push(format!("{name} ({e})")),
            }
        }
        if changed.is_empty() { None } else { Some(format!("changed: {}", changed.join(", "))) }
    }
}

/// The readers a capture file enters, by its first bytes: MAT v5 → `mat`; HDF5 and MAT v7.3 → `hdf5` and
/// `jitter_file` (the timing responses are HDF5); NumPy → `npy`; OpenEXR → `exr`; a JSON sidecar → `npy`.
/// Nothing for a file that is no capture (a mesh).
pub(crate) fn readers_of_file(path: &Path) -> Vec<String> {
    let mut head = vec![0u8; 520];
    let n = std::fs::File::open(path).and_then(|mut f| std::io::Read::read(&mut f, &mut head)).unwrap_or(0);
    head.truncate(n);
    const HDF5: &[u8] = b"\x89HDF\r\n\x1a\n";
    let v: &[&str] = if head.starts_with(HDF5) || (head.starts_with(b"MATLAB") && head.get(512..520) == Some(HDF5)) {
        &["hdf5", "jitter_file"]
    } else if head.starts_with(b"MATLAB") {
        &["mat"]
    } else if head.starts_with(b"\x93NUMPY") {
        &["npy"]
    } else if head.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        &["exr"]
    } else if head.first() == Some(&b'{') {
        &["npy"]
    } else {
        &[]
    };
    v.iter().map(|s| (*s).to_string()).collect()
}

/// The readers a file the scenario wrote itself enters, by its extension (the formats `nlos` writes).
pub(crate) fn readers_of_extension(path: &Path) -> Vec<String> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or_default().to_ascii_lowercase();
    let v: &[&str] = match ext.as_str() {
        "hdf5" | "h5" => &["hdf5", "jitter_file"],
        "npy" | "json" => &["npy"],
        "exr" => &["exr"],
        "mat" => &["mat"],
        _ => &[],
    };
    v.iter().map(|s| (*s).to_string()).collect()
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeSet;

    use super::{Fingerprints, normalized};

    /// The readers a row reaches follow the readers' own references: the OpenEXR reader uses the sidecar and
    /// nothing a MAT or HDF5 capture reaches uses it, so a change to it stales only the rows that read EXR.
    #[test]
    fn a_reader_reaches_the_readers_it_refers_to_and_no_other() {
        let mut fp = Fingerprints::new(&crate::workspace_root());
        let set = |v: &[&str]| v.iter().map(|s| (*s).to_string()).collect::<BTreeSet<String>>();
        let exr = fp.reader_closure(&set(&["exr"])).expect("readers");
        assert_eq!(exr, set(&["exr", "sidecar"]));
        for entry in ["mat", "hdf5", "npy"] {
            let reached = fp.reader_closure(&set(&[entry])).expect("readers");
            assert!(reached.contains(entry) && !reached.contains("exr"), "{entry}: {reached:?}");
        }
        // A name that is no reader reaches nothing.
        assert!(fp.reader_closure(&set(&["mesh"])).expect("readers").is_empty());
    }

    fn same(a: &str, b: &str) -> bool {
        normalized(a).expect("a").to_string() == normalized(b).expect("b").to_string()
    }

    #[test]
    fn comments_docs_lints_and_tests_leave_the_tokens_as_they_are() {
        let base = "pub fn f(x: f32) -> f32 { x * 2.0 }\nfn g() {}\n";
        let commented = "/// Doubles.\n//! Module.\n#[must_use]\n#[allow(clippy::x)]\npub fn f(x: f32) -> f32 {\n    // why\n    x * /* two */ 2.0\n}\n#[cfg_attr(not(feature = \"gpu\"), expect(dead_code))]\nfn g() {}\n#[cfg(test)]\nmod tests { #[test] fn t() { assert!(true) } }\n#[cfg(test)]\nuse std::fmt;\n#[cfg(test)]\nmod more;\n";
        assert!(same(base, commented), "{}\n{}", normalized(base).expect("a"), normalized(commented).expect("b"));
    }

    #[test]
    fn a_change_to_the_code_changes_the_tokens() {
        let base = "pub fn f(x: f32) -> f32 { x * 2.0 }";
        assert!(!same(base, "pub fn f(x: f32) -> f32 { x * 3.0 }"));
        assert!(!same(base, "#[inline(never)] pub fn f(x: f32) -> f32 { x * 2.0 }"));
        assert!(!same(base, "#[cfg(feature = \"gpu\")] pub fn f(x: f32) -> f32 { x * 2.0 }"));
        // A `cfg_attr` that can switch more than a lint on is code.
        assert!(!same(base, "#[cfg_attr(test, derive(Debug))] pub fn f(x: f32) -> f32 { x * 2.0 }"));
        // A `#[cfg(test)]` on a statement removes nothing beyond it.
        let stmt = "fn g() { #[cfg(test)] let a = 1; let b = 2; }";
        assert!(!same(stmt, "fn g() { #[cfg(test)] let a = 1; let b = 3; }"));
    }
}
