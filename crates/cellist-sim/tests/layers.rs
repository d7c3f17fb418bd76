//! The workspace's module structure, read from the source files on disk:
//!
//! - `no_module_cycles`: no import cycle between the modules of any crate (a
//!   module and its ancestors are one tree, not peers: a child that uses what
//!   its parent defines while the parent re-exports the child is no cycle);
//! - `layers_point_one_way`: engine, then files, then simulation, then the
//!   command-line tool and the Python module, which use only the simulation;
//! - `no_long_files`: no source file over 1,000 lines;
//! - `cli_has_no_step_loops`: the command-line tool leaves stepping to the
//!   driver.
//!
//! The code is scanned as tokens, without comments and string and char
//! literals, so neither prose nor a string that mentions `use crate::x` counts.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::fs;
use std::path::{Path, PathBuf};

/// Longest a source file may be, in lines.
const MAX_LINES: usize = 1_000;

/// Each crate's directory and the workspace crates (`-` as `_`) its sources
/// and `[dependencies]` may name.
const LAYERS: &[(&str, &[&str])] = &[
    ("crates/cellist", &[]),
    ("crates/cellist-io", &["cellist"]),
    ("crates/cellist-sim", &["cellist", "cellist_io"]),
    ("crates/cellist-cli", &["cellist_sim"]),
    ("python", &["cellist_sim"]),
];

/// The workspace's root directory.
fn workspace() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    fs::canonicalize(&dir).unwrap_or(dir)
}

/// `path` relative to the workspace, for messages.
fn shown(path: &Path) -> String {
    let root = workspace();
    format!("{}", path.strip_prefix(&root).unwrap_or(path).display())
}

/// Reads `path`, panicking with its name.
fn read(path: &Path) -> String {
    fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The trimmed line `line` (from 1) of `source`.
fn line_of(source: &str, line: usize) -> &str {
    let text = source.lines().nth(line.wrapping_sub(1));
    text.unwrap_or("").trim()
}

/// Fails, listing `found` under `what`, unless `found` is empty.
#[track_caller]
fn assert_none(found: &[String], what: &str) {
    let (count, list) = (found.len(), found.join("\n"));
    assert!(found.is_empty(), "{count} {what}:\n{list}\n");
}

/// The crate directories under `crates/`, sorted.
fn crate_dirs() -> Vec<PathBuf> {
    let entries = fs::read_dir(workspace().join("crates")).expect("crates/ is readable");
    let mut dirs: Vec<PathBuf> = entries.map(|e| e.expect("crates/ entry").path()).collect();
    dirs.retain(|dir| dir.join("Cargo.toml").is_file());
    dirs.sort();
    assert!(dirs.len() >= 4, "the crates under crates/: {dirs:?}");
    dirs
}

/// Every `.rs` file under `dir`, sorted.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let (mut files, mut todo) = (Vec::new(), vec![dir.to_path_buf()]);
    while let Some(dir) = todo.pop() {
        for entry in fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
            let path = entry.expect("directory entry").path();
            if path.is_dir() {
                todo.push(path);
            } else if path.extension().is_some_and(|ext| ext == "rs") {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

/// One token of code: an identifier or keyword, a number, `::` or one other
/// character, with its line (from 1).
#[derive(Clone, Debug)]
struct Tok {
    text: String,
    line: usize,
}

/// The tokens of `src`, skipping comments (doc comments too), string, byte
/// and raw string literals (`r#".."#`) and char literals.
fn tokens(src: &str) -> Vec<Tok> {
    let c: Vec<char> = src.chars().collect();
    let at = |i: usize| c.get(i).copied().unwrap_or('\0');
    let word = |i: usize| at(i).is_alphanumeric() || at(i) == '_';
    let (mut toks, mut line, mut i) = (Vec::new(), 1, 0);
    while i < c.len() {
        let start = i;
        // `r"`, `r#"` or `br#"`, but not the end of a word as in `for"`
        let hashes = (i + 1..c.len()).take_while(|&k| c[k] == '#').count();
        let lone = |k: usize| k == 0 || !word(k - 1);
        let raw = at(i) == 'r' && (lone(i) || (at(i - 1) == 'b' && lone(i - 1)));
        let keep = if at(i) == '/' && at(i + 1) == '/' {
            i = (i..c.len()).find(|&k| c[k] == '\n').unwrap_or(c.len());
            false
        } else if at(i) == '/' && at(i + 1) == '*' {
            let mut depth = 0; // block comments nest
            while i < c.len() {
                let step = match (at(i), at(i + 1)) {
                    ('/', '*') => 1,
                    ('*', '/') => -1,
                    _ => 0,
                };
                depth += step;
                i += if step == 0 { 1 } else { 2 };
                if depth == 0 {
                    break;
                }
            }
            false
        } else if raw && at(i + 1 + hashes) == '"' {
            let close = |k: &usize| at(*k) == '"' && (1..=hashes).all(|h| at(k + h) == '#');
            let end = (i + 2 + hashes..c.len()).find(close);
            i = end.map_or(c.len(), |k| k + 1 + hashes);
            false
        } else if at(i) == '"' {
            i += 1;
            while i < c.len() && at(i) != '"' {
                i += if at(i) == '\\' { 2 } else { 1 };
            }
            i += 1;
            false
        } else if at(i) == '\'' && at(i + 1) == '\\' {
            // `'\n'`, `'\''`, `'\u{7f}'`
            let end = (i + 3..c.len()).find(|&k| c[k] == '\'');
            i = end.map_or(c.len(), |k| k + 1);
            false
        } else if at(i) == '\'' && at(i + 2) == '\'' {
            i += 3; // `'x'`, while a lifetime `'a` is a token `'` and a word
            false
        } else if word(i) {
            // a word, or a number such as `1.5e3` (but `0..n` is three tokens)
            let digit = |k: usize| at(k).is_ascii_digit();
            while word(i) || (digit(start) && at(i) == '.' && digit(i + 1)) {
                i += 1;
            }
            true
        } else {
            i += 1 + usize::from(at(i) == ':' && at(i + 1) == ':');
            !at(start).is_whitespace()
        };
        let text: String = c[start..i.min(c.len())].iter().collect();
        let newlines = text.matches('\n').count();
        if keep {
            toks.push(Tok { text, line });
        }
        line += newlines;
    }
    toks
}

/// The text of `toks[i]`, `""` past either end.
fn text(toks: &[Tok], i: usize) -> &str {
    toks.get(i).map_or("", |t| &t.text)
}

/// Whether `s` is an identifier or keyword.
fn is_ident(s: &str) -> bool {
    s.starts_with(|ch: char| ch.is_alphabetic() || ch == '_')
}

/// The index just past the item that starts at `toks[i]` (attributes
/// included): after its `;` or the `}` closing its body (a `use` ends at its
/// `;`), or at a `}` closing the block around it.
fn item_end(toks: &[Tok], mut i: usize) -> usize {
    let (mut depth, mut is_use) = (0, false);
    while let Some(t) = toks.get(i) {
        match t.text.as_str() {
            "(" | "[" | "{" => depth += 1,
            ")" | "]" | "}" if depth == 0 => return i,
            "}" if depth == 1 && !is_use => return i + 1,
            ")" | "]" | "}" => depth -= 1,
            ";" if depth == 0 => return i + 1,
            "use" if depth == 0 => is_use = true,
            _ => {}
        }
        i += 1;
    }
    i
}

/// `toks` without the items marked `#[cfg(test)]` (test modules, test-only
/// imports and helpers) and without inline modules `mod x { .. }`.
fn module_code(toks: &[Tok]) -> Vec<Tok> {
    let (mut code, mut i) = (Vec::new(), 0);
    while i < toks.len() {
        let attribute: Vec<&str> = (i..i + 7).map(|k| text(toks, k)).collect();
        if attribute == ["#", "[", "cfg", "(", "test", ")", "]"] {
            i = item_end(toks, i + 7);
        } else if toks[i].text == "mod" && text(toks, i + 2) == "{" {
            i = item_end(toks, i);
        } else {
            code.push(toks[i].clone());
            i += 1;
        }
    }
    code
}

/// Expands the use tree at `toks[*i]`, under `prefix`, into full paths in
/// `out`; `*i` ends just after the tree.
fn use_tree(toks: &[Tok], i: &mut usize, prefix: &[Tok], out: &mut Vec<Vec<Tok>>) {
    let mut path = prefix.to_vec();
    while let Some(t) = toks.get(*i) {
        match t.text.as_str() {
            "::" | "*" => *i += 1,
            "as" => *i += 2,
            "," | "}" | ";" => break,
            "{" => {
                *i += 1;
                while toks.get(*i).is_some_and(|t| t.text != "}") {
                    use_tree(toks, i, &path, out);
                    *i += usize::from(text(toks, *i) == ",");
                }
                *i += 1;
                return;
            }
            _ => {
                path.push(t.clone());
                *i += 1;
            }
        }
    }
    out.push(path);
}

/// `parent::child`, or `child` in the crate root `""`.
fn join(parent: &str, child: &str) -> String {
    if parent.is_empty() {
        child.to_string()
    } else {
        format!("{parent}::{child}")
    }
}

/// The module that `path`, written in module `here`, refers to (the longest
/// prefix of it that `exists` as a module), with the line of its last segment
/// in that prefix. `None` for paths that start with none of `crate`, `self`,
/// `super` or a child module of `here`.
fn resolve(here: &str, path: &[Tok], exists: &dyn Fn(&str) -> bool) -> Option<(String, usize)> {
    let (mut target, mut rest, mut line) = (here.to_string(), path, path.first()?.line);
    match path[0].text.as_str() {
        "crate" => (target, rest) = (String::new(), &path[1..]),
        "self" => rest = &path[1..],
        "super" => {
            while rest.first().is_some_and(|t| t.text == "super") {
                if target.is_empty() {
                    return None; // `super` of the crate root
                }
                target.truncate(target.rfind("::").unwrap_or(0));
                rest = &rest[1..];
            }
        }
        child if exists(&join(here, child)) => {}
        _ => return None,
    }
    for segment in rest.iter().filter(|t| t.text != "self") {
        let next = join(&target, &segment.text);
        if !exists(&next) {
            break;
        }
        (target, line) = (next, segment.line);
    }
    Some((target, line))
}

/// One module: its name (`a::b`, `""` for the crate root), file, source and
/// code (`module_code`).
struct Module {
    name: String,
    file: String,
    source: String,
    toks: Vec<Tok>,
}

impl Module {
    /// The module `name` in `file`, of source `source`.
    fn new(name: &str, file: &str, source: &str) -> Module {
        Module {
            name: name.to_string(),
            file: file.to_string(),
            source: source.to_string(),
            toks: module_code(&tokens(source)),
        }
    }

    /// The name in messages: `crate` for the root.
    fn shown(&self) -> &str {
        if self.name.is_empty() {
            "crate"
        } else {
            &self.name
        }
    }
}

/// The modules of the crate whose root file is `root`, found by following the
/// `mod x;` declarations that are not `#[cfg(test)]`.
fn crate_modules(root: &Path) -> Vec<Module> {
    let (mut modules, mut todo) = (Vec::new(), vec![(String::new(), root.to_path_buf())]);
    while let Some((name, file)) = todo.pop() {
        let module = Module::new(&name, &shown(&file), &read(&file));
        // where its child modules are: `src/` for the root, `src/a/` for `a`
        let dir = if name.is_empty() || file.ends_with("mod.rs") {
            file.parent().expect("a source directory").to_path_buf()
        } else {
            file.with_extension("")
        };
        for w in module.toks.windows(3) {
            if w[0].text == "mod" && w[2].text == ";" {
                let flat = dir.join(format!("{}.rs", w[1].text));
                let nested = dir.join(&w[1].text).join("mod.rs");
                let file = if flat.exists() { flat } else { nested };
                todo.push((join(&name, &w[1].text), file));
            }
        }
        modules.push(module);
    }
    modules.sort_by(|a, b| a.name.cmp(&b.name));
    modules
}

/// True when one of the modules `a` and `b` is the other's ancestor (the crate
/// root `""` is everyone's): a parent and its children are one tree, so what
/// passes between them is not an import between peers.
fn related(a: &str, b: &str) -> bool {
    let within =
        |inner: &str, outer: &str| outer.is_empty() || inner.starts_with(&format!("{outer}::"));
    within(a, b) || within(b, a)
}

/// The references between `modules`: (from, to) indices, each with the first
/// line of `from` that refers to `to` through a `use` or a path in code.
fn references(modules: &[Module]) -> BTreeMap<(usize, usize), usize> {
    let names = modules
        .iter()
        .enumerate()
        .map(|(k, m)| (m.name.as_str(), k));
    let index: BTreeMap<&str, usize> = names.collect();
    let exists = |name: &str| index.contains_key(name);
    let mut edges = BTreeMap::new();
    for (from, module) in modules.iter().enumerate() {
        let (toks, mut i) = (&module.toks, 0);
        while i < toks.len() {
            let mut paths = Vec::new();
            let path_start = text(toks, i + 1) == "::" && text(toks, i.wrapping_sub(1)) != "::";
            if toks[i].text == "use" {
                i += 1;
                use_tree(toks, &mut i, &[], &mut paths);
            } else if is_ident(&toks[i].text) && path_start {
                let mut path = vec![toks[i].clone()];
                while text(toks, i + 1) == "::" && is_ident(text(toks, i + 2)) {
                    path.push(toks[i + 2].clone());
                    i += 2;
                }
                paths.push(path);
            }
            i += 1;
            for path in paths {
                if let Some((to, line)) = resolve(&module.name, &path, &exists) {
                    let to = index[to.as_str()];
                    if to != from {
                        edges.entry((from, to)).or_insert(line);
                    }
                }
            }
        }
    }
    edges
}

/// The predecessor of each module on a shortest path from `from` along `adj`
/// (`None` if unreachable; `from` itself has one only if it is on a cycle).
fn bfs(adj: &[Vec<usize>], from: usize) -> Vec<Option<usize>> {
    let (mut parent, mut queue) = (vec![None; adj.len()], VecDeque::from([from]));
    while let Some(v) = queue.pop_front() {
        for &w in &adj[v] {
            if parent[w].is_none() {
                parent[w] = Some(v);
                queue.push_back(w);
            }
        }
    }
    parent
}

/// Each import cycle among `modules` (peers only: [`related`] modules are one
/// tree): one message per strongly connected
/// component of more than one module, with a shortest cycle through its first
/// module, its files, and every import inside it with an example line.
fn cycles(modules: &[Module]) -> Vec<String> {
    let mut edges = references(modules);
    edges.retain(|&(from, to), _| !related(&modules[from].name, &modules[to].name));
    let mut adj = vec![Vec::new(); modules.len()];
    for &(from, to) in edges.keys() {
        adj[from].push(to);
    }
    let reach: Vec<_> = (0..modules.len()).map(|v| bfs(&adj, v)).collect();
    let (mut seen, mut messages) = (BTreeSet::new(), Vec::new());
    for (v, parent) in reach.iter().enumerate() {
        let mutual = |w: usize| w == v || (parent[w].is_some() && reach[w][v].is_some());
        let part: Vec<usize> = (0..modules.len()).filter(|&w| mutual(w)).collect();
        if part.len() < 2 || !seen.insert(part.clone()) {
            continue;
        }
        let mut cycle = vec![v]; // back from v to v along the predecessors
        while let Some(p) = parent[*cycle.last().unwrap()].filter(|&p| p != v) {
            cycle.push(p);
        }
        cycle.push(v);
        let names: Vec<&str> = cycle.iter().rev().map(|&k| modules[k].shown()).collect();
        let files: Vec<&str> = part.iter().map(|&k| modules[k].file.as_str()).collect();
        let (names, files) = (names.join(" -> "), files.join(", "));
        let mut message = format!("\ncycle {names}\n  files: {files}");
        for (&(from, to), &line) in &edges {
            if part.contains(&from) && part.contains(&to) {
                let (a, b) = (&modules[from], modules[to].shown());
                let text = line_of(&a.source, line);
                message += &format!("\n  {} -> {b}: {}:{line}: {text}", a.shown(), a.file);
            }
        }
        messages.push(message);
    }
    messages
}

#[test]
fn no_module_cycles() {
    let mut dirs: Vec<PathBuf> = crate_dirs().iter().map(|dir| dir.join("src")).collect();
    dirs.push(workspace().join("python/src"));
    let roots = dirs
        .iter()
        .flat_map(|dir| [dir.join("lib.rs"), dir.join("main.rs")]);
    let roots = roots.filter(|root| root.is_file());
    let found: Vec<String> = roots
        .flat_map(|root| cycles(&crate_modules(&root)))
        .collect();
    let fix = "the usual fix: move what both sides use into a module of its own";
    assert_none(&found, &format!("import cycle(s) between modules ({fix})"));
}

/// The workspace crates out of `crates` that the manifest `toml` lists as
/// dependencies (`[dependencies]`, `[build-dependencies]`, their `[target.*]`
/// forms; not dev-dependencies), with their lines.
fn manifest_deps(toml: &str, crates: &[String]) -> Vec<(String, usize)> {
    let (mut section, mut found) = (String::new(), Vec::new());
    for (n, line) in toml.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        let mut name = None;
        if line.starts_with('[') {
            section = line.trim_matches(['[', ']']).to_string();
            let table = section.rsplit_once("dependencies."); // `[dependencies.cellist]`
            let table = table.filter(|(head, _)| !head.ends_with("dev-"));
            name = table.map(|(_, dep)| dep);
        } else if section.ends_with("dependencies") && !section.ends_with("dev-dependencies") {
            let package = line.split_once("package").map(|(_, rest)| rest);
            let renamed = package.and_then(|rest| rest.split('"').nth(1));
            name = renamed.or(line.split(['=', '.']).next());
        }
        let name = name.map(|s| s.trim().trim_matches('"').replace('-', "_"));
        if let Some(name) = name.filter(|name| crates.contains(name)) {
            found.push((name, n + 1));
        }
    }
    found
}

/// The workspace crates out of `crates` that the code `toks` names by a path
/// (`cellist_io::x`), a `use` or an `extern crate`, with their lines.
fn crate_uses(toks: &[Tok], crates: &[String]) -> Vec<(String, usize)> {
    let mut found = Vec::new();
    for (i, t) in toks.iter().enumerate() {
        let prev = text(toks, i.wrapping_sub(1));
        let path = text(toks, i + 1) == "::" && prev != "::";
        if crates.contains(&t.text) && (path || prev == "use" || prev == "crate") {
            found.push((t.text.clone(), t.line));
        }
    }
    found
}

#[test]
fn layers_point_one_way() {
    let (root, dirs) = (workspace(), crate_dirs());
    let name = |dir: &PathBuf| dir.file_name().unwrap().to_string_lossy().replace('-', "_");
    let crates: Vec<String> = dirs.iter().map(name).collect();
    for dir in &dirs {
        let known = LAYERS.iter().any(|(layer, _)| root.join(layer) == *dir);
        assert!(known, "add {dir:?} to LAYERS with the crates it may use");
    }
    let mut bad = Vec::new();
    for (dir, allowed) in LAYERS {
        let mut forbidden = crates.clone();
        forbidden.retain(|c| !allowed.contains(&c.as_str()));
        let manifest = root.join(dir).join("Cargo.toml");
        for (name, line) in manifest_deps(&read(&manifest), &forbidden) {
            bad.push(format!("{}:{line}: depends on {name}", shown(&manifest)));
        }
        for file in rust_files(&root.join(dir).join("src")) {
            let source = read(&file);
            for (name, line) in crate_uses(&tokens(&source), &forbidden) {
                let text = line_of(&source, line);
                bad.push(format!("{}:{line}: uses {name}: {text}", shown(&file)));
            }
        }
    }
    assert_none(&bad, &format!("use(s) against the layers {LAYERS:?}"));
}

#[test]
fn no_long_files() {
    let mut long = Vec::new();
    for file in crate_dirs()
        .iter()
        .flat_map(|dir| rust_files(&dir.join("src")))
    {
        let lines = read(&file).lines().count();
        if lines > MAX_LINES {
            long.push(format!("{}: {lines} lines", shown(&file)));
        }
    }
    assert_none(&long, &format!("file(s) over {MAX_LINES} lines, to split"));
}

/// The lines of the `for` loops in `toks` whose pattern or iterator mentions
/// `step` (`for step in ..`, `for _ in 0..args.steps`).
fn step_loops(toks: &[Tok]) -> Vec<usize> {
    let mut found = Vec::new();
    for (i, t) in toks.iter().enumerate().filter(|(_, t)| t.text == "for") {
        let (mut depth, mut seen_in, mut steps) = (0, false, false);
        for t in &toks[i + 1..] {
            match t.text.as_str() {
                "(" | "[" => depth += 1,
                ")" | "]" => depth -= 1,
                "in" if depth == 0 => seen_in = true,
                "{" | ";" if depth == 0 => break, // the loop's body, or `impl X for Y {`
                "<" if depth == 0 && !seen_in => break, // `for<'a>`
                text => steps |= text.to_lowercase().contains("step"),
            }
        }
        if seen_in && steps {
            found.push(t.line);
        }
    }
    found
}

#[test]
fn cli_has_no_step_loops() {
    let mut found = Vec::new();
    for file in rust_files(&workspace().join("crates/cellist-cli/src")) {
        let source = read(&file);
        for line in step_loops(&tokens(&source)) {
            let text = line_of(&source, line);
            found.push(format!("{}:{line}: {text}", shown(&file)));
        }
    }
    let fix = "step through the cellist-sim driver instead";
    assert_none(
        &found,
        &format!("loop(s) over steps in the command-line tool ({fix})"),
    );
}

/// Tests of the scanner on small sources.
mod scanner {
    use super::*;

    /// The imports among the modules `names` (`crate` for the root), of which
    /// those in `sources` have code, as `from -> to`.
    fn imports(names: &[&str], sources: &[(&str, &str)]) -> Vec<String> {
        let mut modules = Vec::new();
        for &name in names {
            let source = sources.iter().find(|(n, _)| *n == name).map_or("", |s| s.1);
            modules.push(Module::new(name.trim_start_matches("crate"), name, source));
        }
        let edge = |&(a, b): &(usize, usize)| [modules[a].shown(), modules[b].shown()].join(" -> ");
        references(&modules).keys().map(edge).collect()
    }

    #[test]
    fn comments_and_strings_are_not_imports() {
        let a = r###"// use crate::b;
            /* use crate::b; /* nested */ crate::b::f(); */
            /// [`x`](crate::b)
            fn f<'a>() { let s = "use crate::b::X;\" crate::b"; let r = r#"crate::b::g()"#; }
            fn g() { let (c, d) = ('"', '\''); let e = br"crate::b"; }"###;
        assert_eq!(imports(&["crate", "a", "b"], &[("a", a)]), [""; 0]);
    }

    #[test]
    fn grouped_uses_and_paths_give_each_edge() {
        let a = "pub(crate) use crate::{\n  b::{self, X},\n  c::d::{Y, Z as W},\n};\nuse super::e;";
        let names = ["crate", "a", "b", "c", "c::d", "e"];
        assert_eq!(
            imports(&names, &[("a", a)]),
            ["a -> b", "a -> c::d", "a -> e"]
        );
        let f = "fn f() -> u8 { crate::b::X + self::g::Y + g::h::Z }\n\
                 #[cfg(test)]\nmod tests { use crate::c; }\nmod inline { use crate::c; }";
        let names = ["crate", "b", "c", "f", "f::g", "f::g::h"];
        assert_eq!(
            imports(&names, &[("f", f)]),
            ["f -> b", "f -> f::g", "f -> f::g::h"]
        );
    }

    #[test]
    fn super_is_a_sibling_if_one_exists_else_the_parent() {
        let b = "use super::c::X;\nuse super::Y;\nuse super::super::Z;";
        let found = imports(&["crate", "a", "a::b", "a::c"], &[("a::b", b)]);
        assert_eq!(found, ["a::b -> crate", "a::b -> a", "a::b -> a::c"]);
    }

    #[test]
    fn a_cycle_is_found_with_its_lines() {
        let b = "use super::c::Thing;\npub struct Shared;";
        let c = "use crate::a::b::Shared;\npub struct Thing;";
        let found = cycles(&[
            Module::new("", "lib.rs", "mod a;"),
            Module::new("a", "a/mod.rs", "mod b;\nmod c;"),
            Module::new("a::b", "a/b.rs", b),
            Module::new("a::c", "a/c.rs", c),
        ]);
        let text = found.join("");
        assert_eq!(found.len(), 1, "{text}");
        assert!(text.starts_with("\ncycle a::b -> a::c -> a::b\n"), "{text}");
        assert!(
            text.contains("\n  a::b -> a::c: a/b.rs:1: use super::c::Thing;"),
            "{text}"
        );
        assert!(
            text.contains("\n  a::c -> a::b: a/c.rs:1: use crate::a::b::Shared;"),
            "{text}"
        );
    }

    #[test]
    fn a_parent_and_its_child_are_no_cycle() {
        let parent = "mod child;\npub use child::Thing;\npub struct Shared;";
        let child = "use super::Shared;\npub struct Thing;";
        assert!(cycles(&[
            Module::new("", "lib.rs", parent),
            Module::new("child", "c.rs", child)
        ])
        .is_empty());
    }

    #[test]
    fn layers_and_step_loops_are_found() {
        let code =
            "use cellist_io::gsd;\nfn f() { cellist::x(); a::cellist::y(); \"cellist::z\"; }";
        let crates = ["cellist".to_string(), "cellist_io".to_string()];
        let found = crate_uses(&tokens(code), &crates);
        assert_eq!(found, [(crates[1].clone(), 1), (crates[0].clone(), 2)]);
        let toml = "[dependencies]\ncellist.workspace = true\nrayon = \"1\"\n\
                    [dev-dependencies]\ncellist-io = { path = \"x\" }\n";
        assert_eq!(manifest_deps(toml, &crates), [(crates[0].clone(), 2)]);
        let code = "impl A for B {}\nfn f() { for step in 1..=n {}\n\
                    for _ in 0..args.steps {}\nfor x in xs {} }";
        assert_eq!(step_loops(&tokens(code)), [2, 3]);
    }
}
