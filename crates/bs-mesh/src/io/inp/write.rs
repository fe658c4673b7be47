//! The `.inp` writer: nodes, element blocks and sets in lines CalculiX reads whole.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::io::{self, Write};

use crate::{ElementKind, Mesh};

fn invalid(msg: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, msg)
}

/// A set name as written in a deck (quoted when it holds spaces), or an error for names an
/// Abaqus deck cannot hold.
fn deck_name(name: &str) -> io::Result<String> {
    let bad = name.is_empty()
        || name.trim() != name
        || name.starts_with('*')
        || name.contains([',', '=', '"', '\n', '\r']);
    if bad {
        return Err(invalid(format!(
            "set name '{name}' cannot be written to an Abaqus deck: names must be non-empty, \
             not start with '*', have no leading/trailing blanks and no ',', '=', '\"' or \
             line breaks"
        )));
    }
    Ok(if name.contains(' ') { format!("\"{name}\"") } else { name.to_string() })
}

/// The most characters CalculiX reads of one coordinate field.
pub const COORD_WIDTH: usize = 20;

/// The most characters per line CalculiX reads.
const LINE_WIDTH: usize = 132;

/// Number of decimal digits of `n`.
fn digits(n: u64) -> usize {
    n.checked_ilog10().map_or(1, |d| d as usize + 1)
}

/// Writes `ids` comma-separated, 16 per line at most and never more than [`LINE_WIDTH`]
/// characters on a line.
fn write_ids(w: &mut dyn Write, ids: impl Iterator<Item = u64>) -> io::Result<()> {
    let mut on_line = 0;
    let mut width = 0;
    for id in ids {
        let len = digits(id);
        if on_line == 16 || (on_line > 0 && width + 2 + len > LINE_WIDTH) {
            writeln!(w)?;
            on_line = 0;
            width = 0;
        }
        if on_line > 0 {
            write!(w, ", ")?;
            width += 2;
        }
        write!(w, "{id}")?;
        width += len;
        on_line += 1;
    }
    if on_line > 0 {
        writeln!(w)?;
    }
    Ok(())
}

/// The shortest of the exact spellings of a number given in Rust's `{:e}` form
/// (`-d.ddde-x`): integer mantissa with exponent (`-dddde-y`) or plain decimal with the
/// leading zero dropped (`-.000dddd`, `ddd.dd`, `dddd00`).
fn compact(sci: &str) -> String {
    let (neg, body) = match sci.strip_prefix('-') {
        Some(b) => (true, b),
        None => (false, sci),
    };
    let (mant, exp) = body.split_once('e').unwrap_or((body, "0"));
    let exp: i32 = exp.parse().unwrap_or(0);
    let mut m: String = mant.chars().filter(char::is_ascii_digit).collect();
    // Value = m × 10^k with m an integer without trailing zeros.
    let mut k = exp - (m.len() as i32 - 1);
    while m.len() > 1 && m.ends_with('0') {
        m.pop();
        k += 1;
    }
    let sign = if neg { "-" } else { "" };
    let with_exp = if k == 0 { format!("{sign}{m}") } else { format!("{sign}{m}e{k}") };
    let point = m.len() as i32 + k; // digits before the decimal point
    let plain = if k >= 0 {
        (k < 20).then(|| format!("{sign}{m}{}", "0".repeat(k as usize)))
    } else if point > 0 {
        let (a, b) = m.split_at(point as usize);
        Some(format!("{sign}{a}.{b}"))
    } else {
        (-point < 20).then(|| format!("{sign}.{}{m}", "0".repeat((-point) as usize)))
    };
    match plain {
        Some(p) if p.len() <= with_exp.len() => p,
        _ => with_exp,
    }
}

/// `-d.ddde-x` with the mantissa cut (toward zero) to `precision` digits after the point.
fn truncate_mantissa(sci: &str, precision: usize) -> String {
    let (mant, exp) = sci.split_once('e').unwrap_or((sci, "0"));
    let keep = mant.find('.').map_or(mant.len(), |dot| (dot + 1 + precision).min(mant.len()));
    format!("{}e{exp}", &mant[..keep])
}

/// A coordinate as written to a deck: exact and readable when it fits in [`COORD_WIDTH`]
/// characters, exact and compact if that fits, else rounded to the most digits that fit.
fn coord_text(x: f64) -> String {
    let debug = format!("{x:?}");
    if debug.len() <= COORD_WIDTH {
        return debug;
    }
    let exact = compact(&format!("{x:e}"));
    if exact.len() <= COORD_WIDTH {
        return exact;
    }
    let sci = format!("{x:e}");
    for precision in (0..16).rev() {
        let mut rounded = compact(&format!("{x:.precision$e}"));
        if rounded.parse::<f64>().is_ok_and(f64::is_infinite) {
            // Rounding up overflowed (|x| next to f64::MAX): cut the digits instead.
            rounded = compact(&truncate_mantissa(&sci, precision));
        }
        if rounded.len() <= COORD_WIDTH {
            return rounded;
        }
    }
    // Unreachable for finite x: one digit with a sign and a 3-digit exponent is 7 characters.
    debug
}

fn check_sets(
    what: &str,
    sets: &BTreeMap<String, Vec<usize>>,
    len: usize,
) -> io::Result<Vec<String>> {
    let mut seen: HashMap<String, &str> = HashMap::new();
    let mut names = Vec::with_capacity(sets.len());
    for (name, members) in sets {
        if let Some(prev) = seen.insert(name.to_ascii_uppercase(), name) {
            return Err(invalid(format!(
                "{what} sets '{prev}' and '{name}' differ only in case; Abaqus set names are \
                 case-insensitive"
            )));
        }
        if let Some(&bad) = members.iter().find(|&&i| i >= len) {
            return Err(invalid(format!(
                "{what} set '{name}' holds index {bad} but the mesh has {len} {what}s"
            )));
        }
        names.push(deck_name(name)?);
    }
    Ok(names)
}

/// Writes `mesh` as an Abaqus/CalculiX deck (see the [module docs](self)). Fails with
/// [`io::ErrorKind::InvalidInput`] for meshes a deck cannot represent faithfully: id vectors
/// of the wrong length, duplicate ids, out-of-range indices, non-finite coordinates, set
/// names that are not valid Abaqus names or that differ only in case. (CalculiX itself also
/// needs ids below 2^31 and set names of at most 80 characters without blanks; this writer
/// does not impose that.)
pub fn write(w: &mut dyn Write, mesh: &Mesh) -> io::Result<()> {
    let nn = mesh.nodes.len();
    if mesh.node_ids.len() != nn || mesh.element_ids.len() != mesh.elements.len() {
        return Err(invalid(format!(
            "mesh has {nn} nodes with {} ids and {} elements with {} ids",
            mesh.node_ids.len(),
            mesh.elements.len(),
            mesh.element_ids.len()
        )));
    }
    let mut seen = HashSet::with_capacity(nn);
    if let Some(id) = mesh.node_ids.iter().find(|&&id| !seen.insert(id)) {
        return Err(invalid(format!("duplicate node id {id}")));
    }
    let mut seen = HashSet::with_capacity(mesh.elements.len());
    if let Some(id) = mesh.element_ids.iter().find(|&&id| !seen.insert(id)) {
        return Err(invalid(format!("duplicate element id {id}")));
    }
    for (e, el) in mesh.elements.iter().enumerate() {
        if let Some(&bad) = el.nodes().iter().find(|&&n| n >= nn) {
            return Err(invalid(format!(
                "element {} references node index {bad} but the mesh has {nn} nodes",
                mesh.element_ids[e]
            )));
        }
    }
    if let Some(i) = mesh.nodes.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(invalid(format!("node {} has a non-finite coordinate", mesh.node_ids[i])));
    }
    let nset_names = check_sets("node", &mesh.node_sets, nn)?;
    let elset_names = check_sets("element", &mesh.element_sets, mesh.elements.len())?;

    writeln!(w, "** Written by brainshift {}", env!("CARGO_PKG_VERSION"))?;
    writeln!(w, "*NODE")?;
    for (p, id) in mesh.nodes.iter().zip(&mesh.node_ids) {
        writeln!(w, "{id}, {}, {}, {}", coord_text(p.x), coord_text(p.y), coord_text(p.z))?;
    }
    let mut current = None;
    for (el, id) in mesh.elements.iter().zip(&mesh.element_ids) {
        if current != Some(el.kind()) {
            current = Some(el.kind());
            let t = match el.kind() {
                ElementKind::Tet4 => "C3D4",
                ElementKind::Hex8 => "C3D8",
            };
            writeln!(w, "*ELEMENT, TYPE={t}")?;
        }
        // Continue on a second line (after a trailing comma) rather than pass 132 characters.
        write!(w, "{id}")?;
        let mut width = digits(*id);
        for &n in el.nodes() {
            let nid = mesh.node_ids[n];
            // Keep room for the trailing comma of a continued line.
            if width + 2 + digits(nid) > LINE_WIDTH - 1 {
                writeln!(w, ",")?;
                write!(w, "{nid}")?;
                width = digits(nid);
            } else {
                write!(w, ", {nid}")?;
                width += 2 + digits(nid);
            }
        }
        writeln!(w)?;
    }
    for ((_, members), name) in mesh.node_sets.iter().zip(&nset_names) {
        writeln!(w, "*NSET, NSET={name}")?;
        write_ids(w, members.iter().map(|&i| mesh.node_ids[i]))?;
    }
    for ((_, members), name) in mesh.element_sets.iter().zip(&elset_names) {
        writeln!(w, "*ELSET, ELSET={name}")?;
        write_ids(w, members.iter().map(|&i| mesh.element_ids[i]))?;
    }
    Ok(())
}
