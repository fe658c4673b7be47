//! The module graph of one crate, read from every `.rs` file under its `src/` (as
//! rust-analyzer's tidy walks every file): module names are paths (`kernels::t4`), and an
//! edge `a → b` means a file of module `a` names module `b` through `crate::…`, `super::…`,
//! `self::…` or a child module's name, in code or in an intra-doc link.
//!
//! * `src/lib.rs` (or `src/main.rs` for a binary-only crate) is the root; `a/mod.rs` and
//!   `a.rs` are module `a`; `a/b.rs` is `a::b`. With a `lib.rs`, `main.rs` and `src/bin/` are
//!   other crates and not read.
//! * A path resolves to the deepest module it names; a name re-exported there
//!   (`pub use …`) is followed to the module it comes from. Paths to the root are not edges
//!   (the root is the facade that declares every module).
//! * A module naming its own submodules (declaring, re-exporting or dispatching to them) is
//!   the module tree, not an edge: a folder's `mod.rs` is its facade. A submodule using its
//!   parent's items is an edge.
//! * `#[cfg(test)]` items and the files of test-only modules (`#[cfg(test)] mod tests;`) are
//!   not read: a test may build the whole model from any layer.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};

use super::source::{Source, Tok, Token};

/// One module: its path (`""` for the root), its file and what was read from it.
#[derive(Debug, Clone)]
pub struct Module {
    /// `kernels::t4`; empty for the crate root.
    pub path: String,
    /// The file, relative to the crate's `src/` parent as given.
    pub file: PathBuf,
    /// The file's tokens and doc links.
    pub source: Source,
}

/// Where an edge was seen first.
#[derive(Debug, Clone, PartialEq)]
pub struct Site {
    /// The importing file.
    pub file: PathBuf,
    /// Its line.
    pub line: usize,
    /// The path as written (`crate::model::Solid`).
    pub text: String,
}

/// A crate's modules and the edges between them (indices into `modules`).
#[derive(Debug, Clone)]
pub struct Graph {
    /// Every module, sorted by path.
    pub modules: Vec<Module>,
    /// `(from, to)` → first site, for every edge.
    pub edges: BTreeMap<(usize, usize), Site>,
}

impl Graph {
    /// The same graph with every file named relative to `root` (for messages).
    pub fn relative_to(mut self, root: &Path) -> Graph {
        let rel = |f: &mut PathBuf| {
            if let Ok(r) = f.strip_prefix(root) {
                *f = r.to_path_buf();
            }
        };
        self.modules.iter_mut().for_each(|m| rel(&mut m.file));
        self.edges.values_mut().for_each(|s| rel(&mut s.file));
        self
    }
}

/// Every `.rs` file under `dir`, sorted.
pub(super) fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) -> Result<(), String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut paths: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    paths.sort();
    for p in paths {
        if p.is_dir() {
            rust_files(&p, out)?;
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
    Ok(())
}

/// The module path of `file` under `src`, or `None` for a file of another crate target.
fn module_path(src: &Path, file: &Path, has_lib: bool) -> Option<String> {
    let rel = file.strip_prefix(src).ok()?.with_extension("");
    let mut parts: Vec<String> =
        rel.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
    match parts.as_slice() {
        [root] if root == "lib" => return Some(String::new()),
        [root] if root == "main" => return (!has_lib).then(String::new),
        [bin, ..] if bin == "bin" && has_lib => return None,
        _ => {}
    }
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    Some(parts.join("::"))
}

fn parent(path: &str) -> Option<&str> {
    if path.is_empty() { None } else { Some(path.rfind("::").map_or("", |k| &path[..k])) }
}

fn join(base: &str, name: &str) -> String {
    if base.is_empty() { name.to_string() } else { format!("{base}::{name}") }
}

/// Reads the modules of the crate whose sources are in `src`.
pub fn read(src: &Path) -> Result<Graph, String> {
    let mut files = Vec::new();
    rust_files(src, &mut files)?;
    let has_lib = src.join("lib.rs").is_file();
    let mut modules = Vec::new();
    for file in files {
        let Some(path) = module_path(src, &file, has_lib) else { continue };
        let text =
            std::fs::read_to_string(&file).map_err(|e| format!("{}: {e}", file.display()))?;
        modules.push(Module { path, file, source: Source::parse(&text) });
    }
    // Test-only modules and everything under them are not part of the graph.
    let tests: BTreeSet<String> = modules
        .iter()
        .flat_map(|m| m.source.test_children.iter().map(|c| join(&m.path, c)))
        .collect();
    modules
        .retain(|m| !tests.iter().any(|t| m.path == *t || m.path.starts_with(&format!("{t}::"))));
    modules.sort_by(|a, b| a.path.cmp(&b.path));
    Ok(Resolver::new(modules).graph())
}

/// A `use` tree or path expanded into full paths, each with its alias (`as name`).
type Paths = Vec<(Vec<String>, Option<String>)>;

/// Parses the path or `use` tree starting at `toks[i]` under `prefix`; returns the index
/// after it.
fn parse_tree(toks: &[Token], mut i: usize, mut prefix: Vec<String>, out: &mut Paths) -> usize {
    loop {
        match toks.get(i).map(|t| &t.tok) {
            Some(Tok::Ident(s)) => {
                prefix.push(s.clone());
                i += 1;
                if matches!(toks.get(i).map(|t| &t.tok), Some(Tok::PathSep)) {
                    i += 1;
                    continue;
                }
                let mut alias = None;
                if let (Some(Tok::Ident(a)), Some(Tok::Ident(name))) =
                    (toks.get(i).map(|t| &t.tok), toks.get(i + 1).map(|t| &t.tok))
                    && a == "as"
                {
                    alias = Some(name.clone());
                    i += 2;
                }
                out.push((prefix, alias));
                return i;
            }
            Some(Tok::Punct('{')) => {
                i += 1;
                while i < toks.len() && !matches!(toks[i].tok, Tok::Punct('}')) {
                    let next = parse_tree(toks, i, prefix.clone(), out);
                    i = if next == i { i + 1 } else { next };
                    if matches!(toks.get(i).map(|t| &t.tok), Some(Tok::Punct(','))) {
                        i += 1;
                    }
                }
                return i + 1;
            }
            _ => {
                out.push((prefix, None));
                return i;
            }
        }
    }
}

/// Whether token `i` is an identifier followed by `::` and not itself after `::` or `.`.
fn path_start(toks: &[Token], i: usize) -> Option<&str> {
    let Tok::Ident(s) = &toks[i].tok else { return None };
    let after_sep = i > 0 && matches!(toks[i - 1].tok, Tok::PathSep | Tok::Punct('.' | '$'));
    let sep_next = matches!(toks.get(i + 1).map(|t| &t.tok), Some(Tok::PathSep));
    (sep_next && !after_sep).then_some(s.as_str())
}

/// Every path of a file: the trees of its `use` items (any first segment) and, elsewhere,
/// paths that start with `crate`, `super`, `self` or one of `children`; with their lines.
fn paths_of(toks: &[Token], children: &BTreeSet<String>) -> Vec<(usize, Vec<String>)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < toks.len() {
        let line = toks[i].line;
        let mut found = Paths::new();
        if matches!(&toks[i].tok, Tok::Ident(u) if u == "use") {
            i = parse_tree(toks, i + 1, Vec::new(), &mut found);
        } else if let Some(s) = path_start(toks, i) {
            if matches!(s, "crate" | "super" | "self") || children.contains(s) {
                i = parse_tree(toks, i, Vec::new(), &mut found);
            } else {
                i += 1;
            }
        } else {
            i += 1;
        }
        out.extend(found.into_iter().map(|(p, _)| (line, p)));
    }
    out
}

/// The `pub use` re-exports of a file: name (or alias) → path as written.
fn reexports(toks: &[Token]) -> HashMap<String, Vec<String>> {
    let mut out = HashMap::new();
    for i in 0..toks.len() {
        if !matches!(&toks[i].tok, Tok::Ident(p) if p == "pub") {
            continue;
        }
        let mut k = i + 1;
        if matches!(toks.get(k).map(|t| &t.tok), Some(Tok::Punct('('))) {
            while k < toks.len() && !matches!(toks[k].tok, Tok::Punct(')')) {
                k += 1;
            }
            k += 1;
        }
        if !matches!(toks.get(k).map(|t| &t.tok), Some(Tok::Ident(u)) if u == "use") {
            continue;
        }
        let mut found = Paths::new();
        parse_tree(toks, k + 1, Vec::new(), &mut found);
        for (mut path, alias) in found {
            if path.last().is_some_and(|s| s == "self") {
                path.pop();
            }
            if let Some(name) = alias.or_else(|| path.last().cloned()) {
                out.insert(name, path);
            }
        }
    }
    out
}

struct Resolver {
    modules: Vec<Module>,
    index: HashMap<String, usize>,
    children: Vec<BTreeSet<String>>,
    reexports: Vec<HashMap<String, Vec<String>>>,
}

impl Resolver {
    fn new(modules: Vec<Module>) -> Self {
        let index: HashMap<String, usize> =
            modules.iter().enumerate().map(|(k, m)| (m.path.clone(), k)).collect();
        let mut children = vec![BTreeSet::new(); modules.len()];
        for m in &modules {
            if let Some(p) = parent(&m.path).and_then(|p| index.get(p)) {
                let name = m.path.rsplit("::").next().unwrap_or(&m.path);
                children[*p].insert(name.to_string());
            }
        }
        let reexports = modules.iter().map(|m| reexports(&m.source.tokens)).collect();
        Resolver { modules, index, children, reexports }
    }

    /// The module that `path`, written in module `from`, names (`None`: outside the crate).
    fn resolve(&self, from: usize, path: &[String], depth: usize) -> Option<usize> {
        let here = self.modules[from].path.as_str();
        let (mut base, rest) = match path.first()?.as_str() {
            "crate" => (String::new(), &path[1..]),
            "self" => (here.to_string(), &path[1..]),
            "super" => {
                let mut b = here;
                let mut k = 0;
                while path.get(k).is_some_and(|s| s == "super") {
                    b = parent(b)?;
                    k += 1;
                }
                (b.to_string(), &path[k..])
            }
            first if self.children[from].contains(first) => (here.to_string(), path),
            _ => return None,
        };
        let mut rest = rest;
        while let Some(seg) = rest.first() {
            let next = join(&base, seg);
            if seg == "self" || !self.index.contains_key(&next) {
                break;
            }
            base = next;
            rest = &rest[1..];
        }
        let target = *self.index.get(&base)?;
        // A name re-exported by the target: follow it to where it comes from.
        if let Some(name) = rest.first()
            && depth < 8
            && let Some(via) = self.reexports[target].get(name)
            && let Some(origin) = self.resolve(target, via, depth + 1)
        {
            return Some(origin);
        }
        Some(target)
    }

    fn graph(self) -> Graph {
        let mut edges = BTreeMap::new();
        for (from, m) in self.modules.iter().enumerate() {
            if m.path.is_empty() {
                continue;
            }
            let mut found = paths_of(&m.source.tokens, &self.children[from]);
            for (line, link) in &m.source.doc_links {
                found.push((*line, link.split("::").map(str::to_string).collect()));
            }
            for (line, path) in found {
                let Some(to) = self.resolve(from, &path, 0) else { continue };
                let target = &self.modules[to].path;
                if to == from || target.is_empty() || target.starts_with(&format!("{}::", m.path)) {
                    continue;
                }
                edges.entry((from, to)).or_insert_with(|| Site {
                    file: m.file.clone(),
                    line,
                    text: path.join("::"),
                });
            }
        }
        Graph { modules: self.modules, edges }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A source tree in a fresh temporary folder, removed on drop.
    pub(crate) struct Tree(pub PathBuf);

    impl Tree {
        pub(crate) fn new(name: &str, files: &[(&str, &str)]) -> Tree {
            let root = std::env::temp_dir()
                .join(format!("xtask-deps-{name}-{}", std::process::id()))
                .join("src");
            let _ = std::fs::remove_dir_all(&root);
            for (path, text) in files {
                let p = root.join(path);
                std::fs::create_dir_all(p.parent().unwrap()).unwrap();
                std::fs::write(p, text).unwrap();
            }
            Tree(root)
        }
    }

    impl Drop for Tree {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(self.0.parent().unwrap());
        }
    }

    pub(crate) fn edge_names(g: &Graph) -> Vec<String> {
        g.edges
            .keys()
            .map(|(a, b)| format!("{} -> {}", g.modules[*a].path, g.modules[*b].path))
            .collect()
    }

    #[test]
    fn paths_resolve_through_super_children_and_reexports() {
        let t = Tree::new(
            "resolve",
            &[
                ("lib.rs", "mod io;\nmod model;\npub use model::Model;\n"),
                ("model.rs", "pub struct Model;\n"),
                ("io/mod.rs", "mod msh;\nmod inp;\npub use msh::read;\nuse inp::Lines;\n"),
                ("io/inp.rs", "pub struct Lines;\nfn f() -> crate::Model { crate::Model }\n"),
                (
                    "io/msh.rs",
                    "use super::{inp::{self, Lines as L}, *};\nuse crate::model;\n\
                     /// See [`super::super::model::Model`].\npub fn read() {}\n",
                ),
                ("main.rs", "use brainshift::io;\nfn main() { crate::nothing::here(); }\n"),
            ],
        );
        let g = read(&t.0).unwrap();
        let paths: Vec<&str> = g.modules.iter().map(|m| m.path.as_str()).collect();
        assert_eq!(paths, ["", "io", "io::inp", "io::msh", "model"]);
        assert_eq!(
            edge_names(&g),
            ["io::inp -> model", "io::msh -> io", "io::msh -> io::inp", "io::msh -> model",]
        );
        // The site of the first sighting, with the path as written.
        let site = &g.edges[&(3, 4)];
        assert_eq!((site.line, site.text.as_str()), (2, "crate::model"));
    }

    #[test]
    fn test_modules_and_binaries_are_not_read() {
        let t = Tree::new(
            "tests",
            &[
                ("lib.rs", "mod a;\nmod b;\n"),
                ("a.rs", "#[cfg(test)]\nmod tests;\npub fn f() {}\n"),
                ("a/tests.rs", "use crate::b::g;\n"),
                ("b.rs", "pub fn g() { crate::a::f() }\n#[cfg(test)]\nmod t { use crate::a; }"),
                ("bin/tool.rs", "use crate::a;\n"),
            ],
        );
        let g = read(&t.0).unwrap();
        assert_eq!(edge_names(&g), ["b -> a"]);
    }
}
