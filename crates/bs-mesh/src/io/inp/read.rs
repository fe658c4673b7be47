//! The `.inp` reader: keywords, nodes, elements and sets read, then resolved into a mesh.

use std::collections::hash_map::Entry;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::Path;

use nalgebra::Point3;

use crate::io::{Lines, ParseError, parse_field};
use crate::{Element, ElementKind, Mesh};

/// What an `*ELEMENT, TYPE=` names.
#[derive(Debug, Clone, Copy)]
enum ElemType {
    /// A supported solid element.
    Solid(ElementKind),
    /// A 1D/2D element that is not part of the volume mesh.
    Skip,
}

/// The fix suggested for unsupported 3D element types.
const LINEAR_FIX: &str = "brainshift solves linear tetrahedra (C3D4) and hexahedra \
    (C3D8/C3D8R) only; convert to linear C3D4, e.g. remesh with first-order elements \
    (`gmsh model.geo -3 -order 1 -o mesh.inp`, or Mesh.ElementOrder = 1), or for C3D10 keep \
    only the first 4 (corner) nodes of each element";

/// Classifies an element type name (already upper-case).
fn classify_type(t: &str) -> Result<ElemType, String> {
    match t {
        "C3D4" | "C3D4H" => return Ok(ElemType::Solid(ElementKind::Tet4)),
        "C3D8" | "C3D8R" | "C3D8H" | "C3D8RH" | "C3D8I" | "C3D8IH" => {
            return Ok(ElemType::Solid(ElementKind::Hex8));
        }
        _ => {}
    }
    const LOWER_DIM: [&str; 33] = [
        "CPS", "CPE", "CAX", "CGAX", "STRI", "SAX", "M3D", "MAX", "MGAX", "SFM", "R2D", "R3D",
        "RAX", "RB2D", "RB3D", "T2D", "T3D", "B2", "B3", "PIPE", "ELBOW", "DC1D", "DC2D", "DCAX",
        "DS", "SPRING", "DASHPOT", "MASS", "ROTARYI", "CONN", "GAP", "F2D", "F3D",
    ];
    let shell = t.len() > 1 && t.starts_with('S') && t.as_bytes()[1].is_ascii_digit();
    if shell || LOWER_DIM.iter().any(|p| t.starts_with(p)) {
        return Ok(ElemType::Skip);
    }
    let what = if let Some(rest) = t.strip_prefix("C3D").or_else(|| t.strip_prefix("DC3D")) {
        let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
        match digits.as_str() {
            "10" => " (10-node quadratic tetrahedron)",
            "20" => " (20-node quadratic hexahedron)",
            "27" => " (27-node hexahedron)",
            "15" => " (15-node quadratic wedge)",
            "13" => " (13-node quadratic pyramid)",
            "6" => " (6-node wedge)",
            "5" => " (5-node pyramid)",
            "4" | "8" => " (a variant brainshift does not know)",
            _ => " (3D continuum element)",
        }
    } else {
        " (unknown element type)"
    };
    Err(format!("element type {t}{what} is not supported: {LINEAR_FIX}"))
}

/// A keyword line: upper-case name and `(UPPER-CASE KEY, value as written)` parameters.
#[derive(Debug)]
struct Keyword {
    name: String,
    params: Vec<(String, String)>,
    line: usize,
}

impl Keyword {
    fn parse(text: &str, line: usize) -> Keyword {
        let body = text.trim().trim_start_matches('*');
        let mut parts = body.split(',');
        let name = parts.next().unwrap_or("").trim().to_ascii_uppercase();
        let params = parts
            .filter(|p| !p.trim().is_empty())
            .map(|p| match p.split_once('=') {
                Some((k, v)) => (k.trim().to_ascii_uppercase(), unquote(v.trim()).to_string()),
                None => (p.trim().to_ascii_uppercase(), String::new()),
            })
            .collect();
        Keyword { name, params, line }
    }

    fn param(&self, key: &str) -> Option<&str> {
        self.params.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    fn has(&self, key: &str) -> bool {
        self.params.iter().any(|(k, _)| k == key)
    }
}

fn unquote(s: &str) -> &str {
    s.strip_prefix('"').and_then(|s| s.strip_suffix('"')).unwrap_or(s)
}

/// At most 40 characters of `s`, for error messages.
pub(crate) fn snippet(s: &str) -> String {
    let s = s.trim();
    match s.char_indices().nth(40) {
        Some((i, _)) => format!("{}…", &s[..i]),
        None => s.to_string(),
    }
}

/// The next data line of the current keyword block (trimmed), skipping comments and blank
/// lines; `None` at the next keyword line (left unconsumed) or the end of the file.
fn next_data<'a>(lines: &mut Lines<'a>) -> Option<(usize, &'a str)> {
    loop {
        let (_, raw) = lines.peek()?;
        let t = raw.trim();
        if t.is_empty() || t.starts_with("**") {
            lines.next_line();
            continue;
        }
        if t.starts_with('*') {
            return None;
        }
        let (ln, _) = lines.next_line()?;
        return Some((ln, t));
    }
}

/// One item of a set definition.
#[derive(Debug)]
enum Item {
    Id(u64),
    Range {
        start: u64,
        end: u64,
        step: u64,
    },
    /// Another set of the same kind, by name.
    Name(Box<str>),
    /// `*NSET, ELSET=…`: the nodes of an element set.
    ElsetNodes(Box<str>),
}

#[derive(Debug)]
struct SetOp {
    node: bool,
    set: usize,
    line: usize,
    item: Item,
}

/// A set being built: name as first written, members (indices), whether skipped 1D/2D
/// element ids were dropped from it.
#[derive(Debug, Default)]
struct SetAcc {
    name: String,
    members: Vec<usize>,
    had_skipped: bool,
}

#[derive(Debug, Default)]
struct Sets {
    list: Vec<SetAcc>,
    by_upper: HashMap<String, usize>,
}

impl Sets {
    fn get_or_create(&mut self, name: &str) -> usize {
        let key = name.to_ascii_uppercase();
        if let Some(&i) = self.by_upper.get(&key) {
            return i;
        }
        self.list.push(SetAcc { name: name.to_string(), ..Default::default() });
        self.by_upper.insert(key, self.list.len() - 1);
        self.list.len() - 1
    }

    fn find(&self, name: &str) -> Option<usize> {
        self.by_upper.get(&name.to_ascii_uppercase()).copied()
    }
}

#[derive(Debug, Default)]
struct Deck {
    nodes: Vec<Point3<f64>>,
    node_ids: Vec<u64>,
    node_lines: Vec<usize>,
    node_map: HashMap<u64, usize>,
    kinds: Vec<ElementKind>,
    conn: Vec<[u64; 8]>,
    element_ids: Vec<u64>,
    element_lines: Vec<usize>,
    element_map: HashMap<u64, usize>,
    skipped: HashSet<u64>,
    nsets: Sets,
    elsets: Sets,
    ops: Vec<SetOp>,
    buf: Vec<u64>,
}

/// Parses an Abaqus/CalculiX input deck. See the [module docs](self) for what is supported.
pub fn read(bytes: &[u8], file: &Path) -> Result<Mesh, ParseError> {
    let mut lines = Lines::new(bytes, file)?;
    let mut deck = Deck::default();
    while let Some((ln, raw)) = lines.next_line() {
        let t = raw.trim();
        if t.is_empty() || t.starts_with("**") {
            continue;
        }
        if !t.starts_with('*') {
            return Err(lines.error(
                ln,
                format!(
                    "expected a keyword line starting with '*' (e.g. *NODE), found data '{}'",
                    snippet(t)
                ),
            ));
        }
        let kw = keyword_with_continuation(&mut lines, t, ln);
        match kw.name.as_str() {
            "NODE" => read_nodes(&mut lines, &kw, &mut deck)?,
            "ELEMENT" => read_elements(&mut lines, &kw, &mut deck)?,
            "NSET" => read_set(&mut lines, &kw, &mut deck, true)?,
            "ELSET" => read_set(&mut lines, &kw, &mut deck, false)?,
            "INCLUDE" => {
                return Err(lines.error(
                    ln,
                    "*INCLUDE is not supported: paste the included file into this deck",
                ));
            }
            _ => while next_data(&mut lines).is_some() {},
        }
    }
    finish(deck, file)
}

/// A keyword line, joined with following lines while it ends with a comma.
fn keyword_with_continuation(lines: &mut Lines<'_>, first: &str, ln: usize) -> Keyword {
    if !first.ends_with(',') {
        return Keyword::parse(first, ln);
    }
    let mut text = first.to_string();
    while text.ends_with(',') {
        match lines.peek() {
            Some((_, next)) if !next.trim().starts_with('*') && !next.trim().is_empty() => {
                text.push_str(next.trim());
                lines.next_line();
            }
            _ => break,
        }
    }
    Keyword::parse(&text, ln)
}

/// A coordinate, accepting Fortran's `D` exponent (`1.5D-3`) besides Rust's float syntax.
fn parse_coordinate(file: &Path, line: usize, field: &str) -> Result<f64, ParseError> {
    let t = field.trim();
    match t.parse::<f64>() {
        Ok(v) => Ok(v),
        Err(_) if t.contains(['d', 'D']) => {
            parse_field(file, line, &t.replace(['d', 'D'], "e"), "a coordinate (number)")
        }
        Err(_) => parse_field(file, line, t, "a coordinate (number)"),
    }
}

fn read_nodes(lines: &mut Lines<'_>, kw: &Keyword, deck: &mut Deck) -> Result<(), ParseError> {
    let file = lines.file();
    if let Some(sys) = kw.param("SYSTEM")
        && !sys.eq_ignore_ascii_case("R")
    {
        return Err(lines.error(
            kw.line,
            format!(
                "*NODE, SYSTEM={sys} is not supported: give rectangular coordinates (SYSTEM=R)"
            ),
        ));
    }
    let nset = kw.param("NSET").map(|n| deck.nsets.get_or_create(n));
    while let Some((ln, t)) = next_data(lines) {
        let mut fields = t.split(',');
        let id: u64 =
            parse_field(file, ln, fields.next().unwrap_or(""), "a node id (non-negative integer)")?;
        let mut c = [0.0f64; 3];
        for ci in &mut c {
            match fields.next() {
                Some(s) if !s.trim().is_empty() => {
                    *ci = parse_coordinate(file, ln, s)?;
                    if !ci.is_finite() {
                        return Err(lines.error(
                            ln,
                            format!("node {id}: coordinate '{}' is not finite", s.trim()),
                        ));
                    }
                }
                _ => {}
            }
        }
        let idx = deck.nodes.len();
        match deck.node_map.entry(id) {
            Entry::Occupied(o) => {
                let first = deck.node_lines[*o.get()];
                return Err(lines.error(
                    ln,
                    format!(
                        "duplicate node id {id}: already defined on line {first}; node ids \
                         must be unique"
                    ),
                ));
            }
            Entry::Vacant(v) => {
                v.insert(idx);
            }
        }
        deck.nodes.push(Point3::new(c[0], c[1], c[2]));
        deck.node_ids.push(id);
        deck.node_lines.push(ln);
        if let Some(s) = nset {
            deck.nsets.list[s].members.push(idx);
        }
    }
    Ok(())
}

fn read_elements(lines: &mut Lines<'_>, kw: &Keyword, deck: &mut Deck) -> Result<(), ParseError> {
    let file = lines.file();
    let type_name = kw.param("TYPE").ok_or_else(|| {
        lines.error(kw.line, "*ELEMENT needs a TYPE= parameter, e.g. *ELEMENT, TYPE=C3D4")
    })?;
    let upper = type_name.to_ascii_uppercase();
    let ty = classify_type(&upper).map_err(|m| lines.error(kw.line, m))?;
    let elset = match ty {
        ElemType::Solid(_) => kw.param("ELSET").map(|n| deck.elsets.get_or_create(n)),
        ElemType::Skip => None,
    };
    let mut buf = std::mem::take(&mut deck.buf);
    while let Some((ln, first)) = next_data(lines) {
        buf.clear();
        let mut cur = first;
        let mut cur_ln = ln;
        loop {
            for f in cur.split(',') {
                let s = f.trim();
                if !s.is_empty() {
                    buf.push(parse_field(file, cur_ln, s, "an element or node id (integer)")?);
                }
            }
            let need_more = match ty {
                ElemType::Solid(k) => buf.len() < 1 + k.node_count(),
                ElemType::Skip => true,
            };
            if !(cur.ends_with(',') && need_more) {
                break;
            }
            match next_data(lines) {
                Some((l2, t2)) => {
                    cur = t2;
                    cur_ln = l2;
                }
                None => {
                    return Err(lines.error(
                        cur_ln,
                        "element data line ends with ',' but no continuation line follows",
                    ));
                }
            }
        }
        match ty {
            ElemType::Skip => {
                if let Some(&id) = buf.first() {
                    deck.skipped.insert(id);
                }
            }
            ElemType::Solid(kind) => {
                let n = kind.node_count();
                if buf.len() != n + 1 {
                    let id = buf.first().map_or_else(|| "?".to_string(), u64::to_string);
                    return Err(lines.error(
                        ln,
                        format!(
                            "element {id} lists {} node ids but {type_name} needs {n} \
                             (expected: element id followed by {n} node ids)",
                            buf.len().saturating_sub(1)
                        ),
                    ));
                }
                let id = buf[0];
                let idx = deck.kinds.len();
                match deck.element_map.entry(id) {
                    Entry::Occupied(o) => {
                        let first = deck.element_lines[*o.get()];
                        return Err(lines.error(
                            ln,
                            format!(
                                "duplicate element id {id}: already defined on line {first}; \
                                 element ids must be unique"
                            ),
                        ));
                    }
                    Entry::Vacant(v) => {
                        v.insert(idx);
                    }
                }
                let mut c = [0u64; 8];
                c[..n].copy_from_slice(&buf[1..]);
                deck.kinds.push(kind);
                deck.conn.push(c);
                deck.element_ids.push(id);
                deck.element_lines.push(ln);
                if let Some(s) = elset {
                    deck.elsets.list[s].members.push(idx);
                }
            }
        }
    }
    deck.buf = buf;
    Ok(())
}

fn read_set(
    lines: &mut Lines<'_>,
    kw: &Keyword,
    deck: &mut Deck,
    node: bool,
) -> Result<(), ParseError> {
    let file = lines.file();
    let (key, what) = if node { ("NSET", "node") } else { ("ELSET", "element") };
    let name = kw.param(key).filter(|n| !n.is_empty()).ok_or_else(|| {
        lines.error(
            kw.line,
            format!("*{key} needs a {key}=<name> parameter, e.g. *{key}, {key}=FIXED"),
        )
    })?;
    let set = if node { deck.nsets.get_or_create(name) } else { deck.elsets.get_or_create(name) };
    let generate = kw.has("GENERATE");
    if node && let Some(es) = kw.param("ELSET") {
        deck.ops.push(SetOp { node, set, line: kw.line, item: Item::ElsetNodes(es.into()) });
    }
    while let Some((ln, t)) = next_data(lines) {
        if generate {
            let mut v = [0u64, 0, 1];
            let mut count = 0;
            for f in t.split(',').map(str::trim).filter(|f| !f.is_empty()) {
                if count == 3 {
                    return Err(lines.error(
                        ln,
                        format!("GENERATE expects 'start, end, step', found '{}'", snippet(t)),
                    ));
                }
                v[count] = parse_field(file, ln, f, &format!("a {what} id (integer)"))?;
                count += 1;
            }
            let [start, end, step] = v;
            if count < 2 || step == 0 || end < start {
                return Err(lines.error(
                    ln,
                    format!(
                        "GENERATE expects 'start, end[, step]' with start <= end and step >= 1, \
                         found '{}'",
                        snippet(t)
                    ),
                ));
            }
            deck.ops.push(SetOp { node, set, line: ln, item: Item::Range { start, end, step } });
        } else {
            for f in t.split(',').map(str::trim).filter(|f| !f.is_empty()) {
                let item = if let Ok(id) = f.parse::<u64>() {
                    Item::Id(id)
                } else if f.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_' || c == '"') {
                    Item::Name(unquote(f).into())
                } else {
                    return Err(lines.error(
                        ln,
                        format!(
                            "expected a {what} id or a {what} set name, found '{}'",
                            snippet(f)
                        ),
                    ));
                };
                deck.ops.push(SetOp { node, set, line: ln, item });
            }
        }
    }
    Ok(())
}

/// Calls `f(id, index)` for every id of `map` in `start..=end` with the given step, touching
/// at most as many entries as the smaller of the range and the map (a mutated `GENERATE`
/// line cannot make this loop for long).
fn for_range(
    map: &HashMap<u64, usize>,
    start: u64,
    end: u64,
    step: u64,
    mut f: impl FnMut(u64, Option<usize>),
) {
    let count = ((end - start) / step).saturating_add(1);
    if count <= map.len() as u64 {
        for k in 0..count {
            let id = start + k * step;
            f(id, map.get(&id).copied());
        }
    } else {
        for (&id, &i) in map {
            if id >= start && id <= end && (id - start).is_multiple_of(step) {
                f(id, Some(i));
            }
        }
    }
}

fn finish(deck: Deck, file: &Path) -> Result<Mesh, ParseError> {
    let err =
        |line: usize, msg: String| ParseError::new(file, crate::io::Location::Line(line), msg);
    let Deck {
        nodes,
        node_ids,
        node_map,
        kinds,
        conn,
        element_ids,
        element_lines,
        element_map,
        skipped,
        mut nsets,
        mut elsets,
        ops,
        ..
    } = deck;

    let mut elements = Vec::with_capacity(kinds.len());
    for (e, (kind, c)) in kinds.iter().zip(&conn).enumerate() {
        let mut idx = [0usize; 8];
        for (slot, &nid) in idx.iter_mut().zip(&c[..kind.node_count()]) {
            *slot = *node_map.get(&nid).ok_or_else(|| {
                err(
                    element_lines[e],
                    format!(
                        "element {} references node {nid}, which no *NODE block defines",
                        element_ids[e]
                    ),
                )
            })?;
        }
        elements.push(match kind {
            ElementKind::Tet4 => Element::tet4([idx[0], idx[1], idx[2], idx[3]]),
            ElementKind::Hex8 => Element::hex8(idx),
        });
    }

    // Element sets first (node sets may use them through ELSET=), each in file order.
    for op in ops.iter().filter(|o| !o.node) {
        let name = &elsets.list[op.set].name;
        match &op.item {
            Item::Id(id) => {
                if let Some(&i) = element_map.get(id) {
                    elsets.list[op.set].members.push(i);
                } else if skipped.contains(id) {
                    elsets.list[op.set].had_skipped = true;
                } else {
                    return Err(err(
                        op.line,
                        format!(
                            "element set '{name}' lists element {id}, which no *ELEMENT block \
                             defines"
                        ),
                    ));
                }
            }
            Item::Range { start, end, step } => {
                let acc = &mut elsets.list[op.set];
                for_range(&element_map, *start, *end, *step, |_, i| {
                    if let Some(i) = i {
                        acc.members.push(i);
                    }
                });
                if skipped.iter().any(|&id| id >= *start && id <= *end) {
                    acc.had_skipped = true;
                }
            }
            Item::Name(other) => {
                let o = elsets
                    .find(other)
                    .ok_or_else(|| err(op.line, format!("element set '{other}' is not defined")))?;
                let members = elsets.list[o].members.clone();
                elsets.list[op.set].members.extend(members);
            }
            Item::ElsetNodes(_) => {}
        }
    }
    for op in ops.iter().filter(|o| o.node) {
        let name = &nsets.list[op.set].name;
        match &op.item {
            Item::Id(id) => {
                let i = *node_map.get(id).ok_or_else(|| {
                    err(
                        op.line,
                        format!("node set '{name}' lists node {id}, which no *NODE block defines"),
                    )
                })?;
                nsets.list[op.set].members.push(i);
            }
            Item::Range { start, end, step } => {
                let acc = &mut nsets.list[op.set];
                for_range(&node_map, *start, *end, *step, |_, i| {
                    if let Some(i) = i {
                        acc.members.push(i);
                    }
                });
            }
            Item::Name(other) => {
                let o = nsets
                    .find(other)
                    .ok_or_else(|| err(op.line, format!("node set '{other}' is not defined")))?;
                let members = nsets.list[o].members.clone();
                nsets.list[op.set].members.extend(members);
            }
            Item::ElsetNodes(es) => {
                let o = elsets.find(es).ok_or_else(|| {
                    err(op.line, format!("ELSET={es}: element set '{es}' is not defined"))
                })?;
                let mut members = Vec::new();
                for &e in &elsets.list[o].members {
                    members.extend_from_slice(elements[e].nodes());
                }
                nsets.list[op.set].members.extend(members);
            }
        }
    }

    let node_sets: BTreeMap<String, Vec<usize>> = nsets
        .list
        .into_iter()
        .map(|mut s| {
            s.members.sort_unstable();
            s.members.dedup();
            (s.name, s.members)
        })
        .collect();
    let element_sets: BTreeMap<String, Vec<usize>> = elsets
        .list
        .into_iter()
        .filter(|s| !(s.members.is_empty() && s.had_skipped))
        .map(|mut s| {
            s.members.sort_unstable();
            s.members.dedup();
            (s.name, s.members)
        })
        .collect();
    Ok(Mesh { nodes, node_ids, elements, element_ids, node_sets, element_sets })
}
