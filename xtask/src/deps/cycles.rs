//! Module cycles: every strongly connected set of two or more modules is one circle,
//! reported with a shortest cycle through it and every edge inside it (file, line, path), so
//! the reader sees what to move.

use std::collections::VecDeque;
use std::fmt::Write as _;

use super::modules::Graph;

/// The strongly connected components of the graph with `n` nodes and adjacency `adj`
/// (Tarjan), each sorted, in order of their smallest node.
pub fn components(n: usize, adj: &[Vec<usize>]) -> Vec<Vec<usize>> {
    struct State<'a> {
        adj: &'a [Vec<usize>],
        index: Vec<Option<usize>>,
        low: Vec<usize>,
        on_stack: Vec<bool>,
        stack: Vec<usize>,
        next: usize,
        out: Vec<Vec<usize>>,
    }
    fn visit(s: &mut State<'_>, v: usize) {
        s.index[v] = Some(s.next);
        s.low[v] = s.next;
        s.next += 1;
        s.stack.push(v);
        s.on_stack[v] = true;
        for &w in &s.adj[v] {
            match s.index[w] {
                None => {
                    visit(s, w);
                    s.low[v] = s.low[v].min(s.low[w]);
                }
                Some(iw) if s.on_stack[w] => s.low[v] = s.low[v].min(iw),
                _ => {}
            }
        }
        if Some(s.low[v]) == s.index[v] {
            let mut c = Vec::new();
            while let Some(w) = s.stack.pop() {
                s.on_stack[w] = false;
                c.push(w);
                if w == v {
                    break;
                }
            }
            c.sort_unstable();
            s.out.push(c);
        }
    }
    let mut s = State {
        adj,
        index: vec![None; n],
        low: vec![0; n],
        on_stack: vec![false; n],
        stack: Vec::new(),
        next: 0,
        out: Vec::new(),
    };
    for v in 0..n {
        if s.index[v].is_none() {
            visit(&mut s, v);
        }
    }
    s.out.sort();
    s.out
}

/// A shortest cycle through `start` using only the nodes of `members` (breadth first).
pub fn shortest_cycle(start: usize, members: &[usize], adj: &[Vec<usize>]) -> Vec<usize> {
    let mut prev: Vec<Option<usize>> = vec![None; adj.len()];
    let mut queue = VecDeque::from([start]);
    while let Some(v) = queue.pop_front() {
        for &w in &adj[v] {
            if !members.contains(&w) {
                continue;
            }
            if w == start {
                let mut path = vec![v];
                while let Some(p) = prev[*path.last().unwrap()] {
                    path.push(p);
                }
                path.reverse();
                if path[0] != start {
                    path.insert(0, start);
                }
                path.push(start);
                return path;
            }
            if prev[w].is_none() && w != start {
                prev[w] = Some(v);
                queue.push_back(w);
            }
        }
    }
    vec![start]
}

/// Every circle of `g`, described for the crate `krate` (empty: none).
pub fn circles(krate: &str, g: &Graph) -> Vec<String> {
    let n = g.modules.len();
    let mut adj = vec![Vec::new(); n];
    for &(a, b) in g.edges.keys() {
        adj[a].push(b);
    }
    let name = |k: usize| g.modules[k].path.clone();
    let mut out = Vec::new();
    for c in components(n, &adj).into_iter().filter(|c| c.len() > 1) {
        let cycle = shortest_cycle(c[0], &c, &adj);
        let path: Vec<String> = cycle.iter().map(|&k| name(k)).collect();
        let mut text = format!(
            "{krate}: module cycle {} ({} modules in the circle: {}); move what they share into \
             a module below them. Imports inside the circle:",
            path.join(" -> "),
            c.len(),
            c.iter().map(|&k| name(k)).collect::<Vec<_>>().join(", "),
        );
        for ((a, b), site) in g.edges.iter().filter(|((a, b), _)| c.contains(a) && c.contains(b)) {
            let _ = write!(
                text,
                "\n    {}:{} {} ({} -> {})",
                site.file.display(),
                site.line,
                site.text,
                name(*a),
                name(*b)
            );
        }
        out.push(text);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::modules::{read, tests::Tree};
    use super::*;

    #[test]
    fn components_and_shortest_cycles() {
        // 0 -> 1 -> 2 -> 0 and 2 -> 3 -> 2; 4 alone; 5 -> 4.
        let adj = vec![vec![1], vec![2], vec![0, 3], vec![2], vec![], vec![4]];
        let c = components(6, &adj);
        assert_eq!(c, vec![vec![0, 1, 2, 3], vec![4], vec![5]]);
        assert_eq!(shortest_cycle(0, &c[0], &adj), vec![0, 1, 2, 0]);
        assert_eq!(shortest_cycle(3, &c[0], &adj), vec![3, 2, 3]);
    }

    #[test]
    fn a_super_cycle_is_reported_with_its_sites() {
        let t = Tree::new(
            "super-cycle",
            &[
                ("lib.rs", "mod a;\nmod b;\nmod c;\n"),
                ("a.rs", "use super::b::B;\npub struct A;\n"),
                ("b.rs", "pub struct B;\nfn f(_: super::a::A) {}\n"),
                ("c.rs", "use crate::a::A;\n"),
            ],
        );
        let found = circles("demo", &read(&t.0).unwrap());
        assert_eq!(found.len(), 1, "{found:?}");
        assert!(found[0].starts_with("demo: module cycle a -> b -> a (2 modules"), "{}", found[0]);
        assert!(found[0].contains("a.rs:1 super::b::B (a -> b)"), "{}", found[0]);
        assert!(found[0].contains("b.rs:2 super::a::A (b -> a)"), "{}", found[0]);
    }

    #[test]
    fn a_nested_folder_cycle_is_found() {
        let t = Tree::new(
            "nested-cycle",
            &[
                ("lib.rs", "pub mod io;\n"),
                ("io/mod.rs", "mod msh;\nmod msh_binary;\npub(crate) struct Lines;\n"),
                ("io/msh.rs", "use super::Lines;\nfn r() { super::msh_binary::read() }\n"),
                ("io/msh_binary.rs", "use crate::io::msh::{Header, r as read};\n"),
            ],
        );
        let found = circles("bs-mesh", &read(&t.0).unwrap());
        assert_eq!(found.len(), 1, "{found:?}");
        assert!(found[0].contains("io::msh -> io::msh_binary -> io::msh"), "{}", found[0]);
    }

    #[test]
    fn a_clean_tree_has_no_circle() {
        let t = Tree::new(
            "clean",
            &[
                ("lib.rs", "pub mod element;\npub mod model;\npub use model::Model;\n"),
                (
                    "element.rs",
                    "//! No `crate::model` here.\nconst S: &str = \"crate::model::X\";\n",
                ),
                ("model.rs", "use crate::element;\npub struct Model;\n#[cfg(test)]\nmod tests;\n"),
                ("model/tests.rs", "use crate::element;\n"),
                ("element/tet.rs", "use crate::Model;\n"),
            ],
        );
        let g = read(&t.0).unwrap();
        // `element/tet.rs` is a file of no declared module, read all the same (tidy walks
        // every file): its edge to `model` goes up but closes no circle.
        assert_eq!(circles("clean", &g), Vec::<String>::new());
        assert_eq!(g.edges.len(), 2);
    }
}
