//! VTK legacy unstructured grids (`.vtk`).
//!
//! Reader: `ASCII` and `BINARY` (big-endian) files with `DATASET UNSTRUCTURED_GRID`,
//! `POINTS`, `CELLS` in the classic form (`n i0 … in-1` per cell) or the VTK 5.1 form
//! (`OFFSETS` + `CONNECTIVITY`), `CELL_TYPES`, and `POINT_DATA` / `CELL_DATA` with `SCALARS`
//! (optional component count and `LOOKUP_TABLE`), `VECTORS`, `NORMALS`, `TENSORS` and `FIELD`
//! arrays (`METADATA` blocks are skipped). Arrays named `node_id`, `element_id`,
//! `nset:<NAME>` and `elset:<NAME>` become ids and sets as in the VTU reader; the rest become
//! [`Fields`]. Cells are handled as in [`vtu`](super::vtu): tetrahedra and hexahedra kept,
//! surface and line cells skipped, other volume cells an error naming the cell.
//!
//! The frame of the coordinates travels in the title line as 3D Slicer writes and reads it:
//! `SPACE=RAS` or `SPACE=LPS` anywhere in the line (Slicer's model storage node looks for it
//! there in legacy files, and for a `SPACE` String field-data array in XML ones). The reader
//! returns it as the field-data string `SPACE`, as the VTU reader does.
//!
//! Writer: version 4.2 ASCII (readable by every VTK, ParaView and meshio), classic `CELLS`,
//! coordinates and field values in Rust's shortest round-trip notation so that a
//! write→read round trip is exact. Ids and sets are written as `FIELD` arrays (`node_id` and
//! `element_id` as `unsigned_long`, sets as `unsigned_char` membership flags). Names are
//! written with spaces and other special characters as `%XX` (the legacy-VTK convention).

use std::io::{self, Write};
use std::path::Path;

use super::vtu::{Array, Cells, Data, assemble, check_for_write};
use super::{Fields, Location, ParseError};
use crate::{ElementKind, Mesh};

/// Byte cursor over a legacy VTK file: whitespace-separated tokens with line numbers, and raw
/// binary blocks.
struct Cursor<'a> {
    b: &'a [u8],
    pos: usize,
    line: usize,
    file: &'a Path,
    binary: bool,
}

impl<'a> Cursor<'a> {
    fn err_line(&self, line: usize, msg: impl Into<String>) -> ParseError {
        ParseError::new(self.file, Location::Line(line), msg)
    }

    fn skip_ws(&mut self) {
        while let Some(&c) = self.b.get(self.pos) {
            if !c.is_ascii_whitespace() {
                break;
            }
            if c == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
    }

    /// The next token with its line, or `None` at the end of the file.
    fn token(&mut self) -> Option<(&'a str, usize)> {
        self.skip_ws();
        let start = self.pos;
        while self.pos < self.b.len() && !self.b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if start == self.pos {
            return None;
        }
        // Non-UTF-8 bytes cannot be part of a valid token: show them lossily in errors.
        Some((std::str::from_utf8(&self.b[start..self.pos]).unwrap_or("\u{fffd}"), self.line))
    }

    fn expect_token(&mut self, what: &str) -> Result<(&'a str, usize), ParseError> {
        self.token().ok_or_else(|| {
            self.err_line(self.line, format!("unexpected end of file: expected {what}"))
        })
    }

    fn peek_token(&mut self) -> Option<&'a str> {
        let (pos, line) = (self.pos, self.line);
        let t = self.token().map(|t| t.0);
        self.pos = pos;
        self.line = line;
        t
    }

    fn count(&mut self, what: &str) -> Result<(usize, usize), ParseError> {
        let (t, line) = self.expect_token(what)?;
        let n = t
            .parse::<usize>()
            .map_err(|_| self.err_line(line, format!("expected {what}, found '{t}'")))?;
        Ok((n, line))
    }

    /// The rest of the current line (without the newline), consuming it.
    fn rest_of_line(&mut self) -> &'a str {
        let start = self.pos;
        while self.pos < self.b.len() && self.b[self.pos] != b'\n' {
            self.pos += 1;
        }
        let s = std::str::from_utf8(&self.b[start..self.pos]).unwrap_or("");
        if self.pos < self.b.len() {
            self.pos += 1;
            self.line += 1;
        }
        s.trim_end_matches('\r')
    }

    /// Reads `n` values of VTK type `ty` (ASCII tokens or big-endian binary).
    fn values(&mut self, n: usize, ty: &str, line: usize, what: &str) -> Result<Data, ParseError> {
        let float = matches!(ty, "float" | "double" | "vtktypefloat32" | "vtktypefloat64");
        let size = type_size(ty).ok_or_else(|| {
            self.err_line(
                line,
                format!("{what}: data type '{ty}' is not supported (use double, float or an integer type)"),
            )
        })?;
        if !self.binary {
            // Each value needs at least two bytes (digit and separator, none after the last):
            // a count the rest of the file cannot hold is refused before allocating or reading
            // on into the next section.
            let left = self.b.len() - self.pos;
            let room = left / 2 + 1;
            if n > room {
                return Err(self.err_line(
                    line,
                    format!(
                        "unexpected end of file: {what} has room for at most {room} of its {n} \
                         values in the {left} bytes left (2 bytes each at least); the count is \
                         corrupt or the file is truncated"
                    ),
                ));
            }
            let cap = n;
            let mut data = if float {
                Data::F(Vec::with_capacity(cap))
            } else {
                Data::I(Vec::with_capacity(cap))
            };
            for k in 0..n {
                let (t, l) = self.token().ok_or_else(|| {
                    self.err_line(
                        self.line,
                        format!("unexpected end of file: {what} has {k} of {n} values"),
                    )
                })?;
                match &mut data {
                    Data::F(v) => v.push(t.parse::<f64>().map_err(|_| {
                        self.err_line(l, format!("{what}: expected a number, found '{t}'"))
                    })?),
                    Data::I(v) => v.push(
                        t.parse::<i64>().or_else(|_| t.parse::<u64>().map(|u| u as i64)).map_err(
                            |_| {
                                self.err_line(
                                    l,
                                    format!("{what}: expected an integer, found '{t}'"),
                                )
                            },
                        )?,
                    ),
                }
            }
            return Ok(data);
        }
        // Binary: the data starts on the line after the keyword line (which may already be
        // consumed, e.g. after `SCALARS name type` without a lookup table).
        if self.pos > 0 && self.b[self.pos - 1] != b'\n' {
            self.rest_of_line();
        }
        let start = self.pos;
        let bytes =
            n.checked_mul(size).filter(|&len| len <= self.b.len() - start).ok_or_else(|| {
                ParseError::new(
                    self.file,
                    Location::Byte(start),
                    format!(
                        "{what}: {n} binary {ty} values need {} bytes, only {} remain",
                        n as u128 * size as u128,
                        self.b.len() - start
                    ),
                )
            })?;
        let raw = &self.b[start..start + bytes];
        self.pos = start + bytes;
        self.line += raw.iter().filter(|&&b| b == b'\n').count();
        let ch = raw.chunks_exact(size);
        let be8 = |c: &[u8]| {
            let mut a = [0u8; 8];
            a[8 - c.len()..].copy_from_slice(c);
            a
        };
        let signed = |c: &[u8]| {
            // Sign-extend a big-endian integer of c.len() bytes.
            let u = u64::from_be_bytes(be8(c));
            let shift = 64 - 8 * c.len() as u32;
            ((u << shift) as i64) >> shift
        };
        Ok(match (float, size) {
            (true, 4) => {
                Data::F(ch.map(|c| f32::from_be_bytes([c[0], c[1], c[2], c[3]]) as f64).collect())
            }
            (true, _) => Data::F(ch.map(|c| f64::from_be_bytes(be8(c))).collect()),
            (false, _) if is_unsigned(ty) => {
                Data::I(ch.map(|c| u64::from_be_bytes(be8(c)) as i64).collect())
            }
            (false, _) => Data::I(ch.map(signed).collect()),
        })
    }

    /// Skips a `METADATA` block (it ends at an empty line).
    fn skip_metadata(&mut self) {
        if self.peek_token() == Some("METADATA") {
            self.token();
            self.rest_of_line();
            while self.pos < self.b.len() {
                if self.rest_of_line().trim().is_empty() {
                    break;
                }
            }
        }
    }
}

fn type_size(ty: &str) -> Option<usize> {
    Some(match ty {
        "unsigned_char" | "char" | "vtktypeint8" | "vtktypeuint8" => 1,
        "unsigned_short" | "short" | "vtktypeint16" | "vtktypeuint16" => 2,
        "unsigned_int" | "int" | "float" | "vtktypeint32" | "vtktypeuint32" | "vtktypefloat32" => 4,
        "unsigned_long" | "long" | "double" | "vtkIdType" | "vtktypeint64" | "vtktypeuint64"
        | "vtktypefloat64" => 8,
        _ => return None,
    })
}

fn is_unsigned(ty: &str) -> bool {
    ty.starts_with("unsigned") || ty.starts_with("vtktypeuint")
}

/// Decodes `%XX` escapes of legacy VTK names.
fn decode_name(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%'
            && i + 2 < b.len()
            && b[i + 1].is_ascii_hexdigit()
            && b[i + 2].is_ascii_hexdigit()
        {
            let hex = |c: u8| (c as char).to_digit(16).unwrap_or(0) as u8;
            out.push(hex(b[i + 1]) << 4 | hex(b[i + 2]));
            i += 3;
            continue;
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Encodes a name for a legacy VTK file: whitespace, `%` and non-printable bytes as `%XX`.
fn encode_name(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for &c in s.as_bytes() {
        if c.is_ascii_graphic() && c != b'%' {
            out.push(c as char);
        } else {
            out.push_str(&format!("%{c:02X}"));
        }
    }
    out
}

/// Which attribute section arrays currently go to.
#[derive(Clone, Copy, PartialEq)]
enum Section {
    None,
    Point(usize),
    Cell(usize),
}

/// The header of a legacy VTK file: the cursor after `DATASET <type>`, the frame named in
/// the title line, the dataset type (upper case) and its line.
fn open<'a>(
    bytes: &'a [u8],
    file: &'a Path,
) -> Result<(Cursor<'a>, Option<&'static str>, String, usize), ParseError> {
    // A UTF-8 byte-order mark before the header is skipped (byte offsets stay file offsets).
    let bom = bytes.len() - super::strip_bom(bytes).len();
    let mut c = Cursor { b: bytes, pos: bom, line: 1, file, binary: false };
    let first = c.rest_of_line();
    if !first.trim_start().starts_with("# vtk DataFile Version") {
        return Err(c.err_line(
            1,
            "expected '# vtk DataFile Version x.y' on the first line: not a legacy VTK file",
        ));
    }
    let title = c.rest_of_line();
    let space = title.split_whitespace().find_map(|w| w.strip_prefix("SPACE=")).and_then(|v| {
        let v = v.trim_end_matches([',', ';', '.']);
        ["RAS", "LPS"].into_iter().find(|s| v.eq_ignore_ascii_case(s))
    });
    let fmt_line = c.line;
    let fmt = c.rest_of_line().trim().to_ascii_uppercase();
    c.binary = match fmt.as_str() {
        "ASCII" => false,
        "BINARY" => true,
        _ => {
            return Err(
                c.err_line(fmt_line, format!("expected ASCII or BINARY on line 3, found '{fmt}'"))
            );
        }
    };
    let (kw, line) = c.expect_token("DATASET")?;
    if !kw.eq_ignore_ascii_case("DATASET") {
        return Err(c.err_line(line, format!("expected 'DATASET <type>', found '{kw}'")));
    }
    let (ds, line) = c.expect_token("the dataset type")?;
    Ok((c, space, ds.to_ascii_uppercase(), line))
}

/// The points of a legacy VTK file of any dataset with a `POINTS` section (`POLYDATA`, as a
/// point cloud or a surface, or `UNSTRUCTURED_GRID`): its vertices, whatever cells it has.
pub fn read_points(bytes: &[u8], file: &Path) -> Result<Vec<nalgebra::Point3<f64>>, ParseError> {
    let (mut c, _, ds, line) = open(bytes, file)?;
    if !matches!(ds.as_str(), "POLYDATA" | "UNSTRUCTURED_GRID") {
        return Err(c.err_line(
            line,
            format!("dataset type {ds}; a point cloud is POLYDATA (or UNSTRUCTURED_GRID)"),
        ));
    }
    while let Some((kw, line)) = c.token() {
        if kw.eq_ignore_ascii_case("POINTS") {
            let (n, _) = c.count("the number of points")?;
            let (ty, _) = c.expect_token("the point data type")?;
            let nv = n.checked_mul(3).ok_or_else(|| c.err_line(line, "point count too large"))?;
            let data = c.values(nv, ty, line, "POINTS")?;
            let array = Array { name: "Points".into(), ncomp: 3, data, loc: Location::Line(line) };
            return super::vtu::points_of(file, n, &array);
        }
    }
    Err(ParseError::new(file, Location::File, "no POINTS section: the file holds no points"))
}

/// Parses a legacy VTK unstructured grid (ASCII or big-endian BINARY).
pub fn read(bytes: &[u8], file: &Path) -> Result<(Mesh, Fields), ParseError> {
    let (c, space, ds, line) = open(bytes, file)?;
    if ds != "UNSTRUCTURED_GRID" {
        return Err(c.err_line(
            line,
            format!("dataset type {ds}; only UNSTRUCTURED_GRID holds a volume mesh (convert it with ParaView or meshio)"),
        ));
    }
    let mut g = Grid::new(c);
    while let Some((kw, line)) = g.c.token() {
        g.section_at(kw, line)?;
    }
    let (mesh, mut fields) = g.finish(file)?;
    if let Some(space) = space {
        fields.field_data.push(("SPACE".into(), space.into()));
    }
    Ok((mesh, fields))
}

/// An unstructured grid as its sections are read: one method per keyword.
struct Grid<'a> {
    c: Cursor<'a>,
    points: Option<(usize, Array)>,
    cells: Cells,
    /// The declared cell count and the line declaring it.
    ncells_decl: Option<(usize, usize)>,
    section: Section,
    pdata: Vec<Array>,
    cdata: Vec<Array>,
}

impl<'a> Grid<'a> {
    fn new(c: Cursor<'a>) -> Self {
        Grid {
            c,
            points: None,
            cells: Cells::default(),
            ncells_decl: None,
            section: Section::None,
            pdata: Vec::new(),
            cdata: Vec::new(),
        }
    }

    /// Reads the section the keyword `kw` (on `line`) opens.
    fn section_at(&mut self, kw: &'a str, line: usize) -> Result<(), ParseError> {
        let kw_up = kw.to_ascii_uppercase();
        match kw_up.as_str() {
            "POINTS" => self.points_section(line),
            "CELLS" => self.cells_section(line),
            "CELL_TYPES" => {
                let c = &mut self.c;
                let (n, _) = c.count("the number of cell types")?;
                self.cells.types =
                    ints(c.values(n, "int", line, "CELL_TYPES")?, c, line, "CELL_TYPES")?;
                c.skip_metadata();
                Ok(())
            }
            "POINT_DATA" => {
                self.section = Section::Point(self.c.count("the number of points")?.0);
                Ok(())
            }
            "CELL_DATA" => {
                self.section = Section::Cell(self.c.count("the number of cells")?.0);
                Ok(())
            }
            "FIELD" => self.field_section(),
            "SCALARS"
            | "VECTORS"
            | "NORMALS"
            | "TENSORS"
            | "TEXTURE_COORDINATES"
            | "COLOR_SCALARS"
            | "GLOBAL_IDS"
            | "PEDIGREE_IDS" => self.attribute(kw, &kw_up, line),
            "LOOKUP_TABLE" => {
                let c = &mut self.c;
                c.expect_token("the lookup table name")?;
                let (n, _) = c.count("the lookup table size")?;
                let n4 =
                    n.checked_mul(4).ok_or_else(|| c.err_line(line, "lookup table too large"))?;
                let ty = if c.binary { "unsigned_char" } else { "float" };
                c.values(n4, ty, line, "LOOKUP_TABLE")?;
                Ok(())
            }
            "METADATA" => {
                let c = &mut self.c;
                c.rest_of_line();
                while c.pos < c.b.len() && !c.rest_of_line().trim().is_empty() {}
                Ok(())
            }
            _ => Err(self.c.err_line(
                line,
                format!(
                    "unexpected '{kw}': expected POINTS, CELLS, CELL_TYPES, POINT_DATA, \
                     CELL_DATA or a data array keyword"
                ),
            )),
        }
    }

    fn points_section(&mut self, line: usize) -> Result<(), ParseError> {
        let c = &mut self.c;
        let (n, _) = c.count("the number of points")?;
        let (ty, _) = c.expect_token("the point data type")?;
        let nv = n.checked_mul(3).ok_or_else(|| c.err_line(line, "point count too large"))?;
        let data = c.values(nv, ty, line, "POINTS")?;
        self.points =
            Some((n, Array { name: "Points".into(), ncomp: 3, data, loc: Location::Line(line) }));
        c.skip_metadata();
        Ok(())
    }

    /// `CELLS`: the VTK 5 form (`OFFSETS` and `CONNECTIVITY` arrays) or the classic list of
    /// counts each followed by its nodes.
    fn cells_section(&mut self, line: usize) -> Result<(), ParseError> {
        let (a, _) = self.c.count("the number of cells")?;
        let (size, _) = self.c.count("the cell list size")?;
        self.cells.loc = Some(Location::Line(line));
        if self.c.peek_token() == Some("OFFSETS") {
            self.c.token();
            self.offsets_and_connectivity(a, size, line)?;
            self.ncells_decl = Some((a.saturating_sub(1), line));
        } else {
            self.classic_cell_list(a, size, line)?;
            self.ncells_decl = Some((a, line));
        }
        self.c.skip_metadata();
        Ok(())
    }

    fn offsets_and_connectivity(
        &mut self,
        a: usize,
        size: usize,
        line: usize,
    ) -> Result<(), ParseError> {
        let c = &mut self.c;
        let (ty, l) = c.expect_token("the offsets type")?;
        let off = ints(c.values(a, ty, l, "OFFSETS")?, c, l, "OFFSETS")?;
        let (kw2, l2) = c.expect_token("CONNECTIVITY")?;
        if kw2 != "CONNECTIVITY" {
            return Err(c.err_line(l2, format!("expected CONNECTIVITY, found '{kw2}'")));
        }
        let (ty, l) = c.expect_token("the connectivity type")?;
        self.cells.connectivity =
            ints(c.values(size, ty, l, "CONNECTIVITY")?, c, l, "CONNECTIVITY")?;
        if off.first().is_some_and(|&o| o != 0) {
            return Err(c.err_line(line, "OFFSETS must start with 0"));
        }
        self.cells.offsets = off.get(1..).unwrap_or(&[]).to_vec();
        Ok(())
    }

    fn classic_cell_list(&mut self, a: usize, size: usize, line: usize) -> Result<(), ParseError> {
        let c = &mut self.c;
        let list = ints(c.values(size, "int", line, "CELLS")?, c, line, "CELLS")?;
        let (mut conn, mut offs) =
            (Vec::with_capacity(list.len()), Vec::with_capacity(a.min(list.len())));
        let mut p = 0usize;
        for i in 0..a {
            let k = *list.get(p).ok_or_else(|| {
                c.err_line(
                    line,
                    format!("CELLS lists {a} cells but its {size} numbers end in cell {i}"),
                )
            })?;
            let end = usize::try_from(k)
                .ok()
                .and_then(|k| (p + 1).checked_add(k))
                .filter(|&e| e <= list.len())
                .ok_or_else(|| {
                    c.err_line(
                        line,
                        format!(
                            "cell {i} declares {k} nodes, beyond the CELLS list of {size} numbers"
                        ),
                    )
                })?;
            conn.extend_from_slice(&list[p + 1..end]);
            offs.push(conn.len() as i64);
            p = end;
        }
        if p != list.len() {
            return Err(c.err_line(
                line,
                format!("CELLS size is {size} but the {a} cells use {p} numbers"),
            ));
        }
        self.cells.connectivity = conn;
        self.cells.offsets = offs;
        Ok(())
    }

    /// `FIELD name n` and its `n` arrays; dataset-level field data (e.g. TIME, before any
    /// POINT_DATA or CELL_DATA) is read past, not kept as mesh data.
    fn field_section(&mut self) -> Result<(), ParseError> {
        let c = &mut self.c;
        c.expect_token("the field name")?;
        let (narrays, _) = c.count("the number of arrays")?;
        for _ in 0..narrays {
            let (name, l) = c.expect_token("an array name")?;
            let (ncomp, _) = c.count("the number of components")?;
            let (ntuples, _) = c.count("the number of tuples")?;
            let (ty, _) = c.expect_token("the array data type")?;
            let n = ncomp.checked_mul(ntuples).ok_or_else(|| c.err_line(l, "array too large"))?;
            let data = c.values(n, ty, l, &format!("array '{name}'"))?;
            c.skip_metadata();
            let a = Array { name: decode_name(name), ncomp, data, loc: Location::Line(l) };
            match self.section {
                Section::Point(_) => self.pdata.push(a),
                Section::Cell(_) => self.cdata.push(a),
                Section::None => {}
            }
        }
        Ok(())
    }

    /// A data attribute (`SCALARS`, `VECTORS`, …) of the current POINT_DATA or CELL_DATA.
    fn attribute(&mut self, kw: &str, kw_up: &str, line: usize) -> Result<(), ParseError> {
        let count = match self.section {
            Section::Point(n) | Section::Cell(n) => n,
            Section::None => {
                return Err(self.c.err_line(line, format!("{kw} before POINT_DATA or CELL_DATA")));
            }
        };
        let c = &mut self.c;
        let (name, _) = c.expect_token("the array name")?;
        let (ncomp, ty) = attribute_shape(c, kw_up, line)?;
        let n = ncomp.checked_mul(count).ok_or_else(|| c.err_line(line, "array too large"))?;
        let mut data = c.values(n, ty, line, &format!("{kw} '{name}'"))?;
        if kw_up == "COLOR_SCALARS" && c.binary {
            // Binary colour scalars are bytes standing for [0, 1].
            data = Data::F(match data {
                Data::I(v) => v.iter().map(|&x| x as f64 / 255.0).collect(),
                Data::F(v) => v,
            });
        }
        c.skip_metadata();
        let a = Array { name: decode_name(name), ncomp, data, loc: Location::Line(line) };
        match self.section {
            Section::Point(_) => self.pdata.push(a),
            _ => self.cdata.push(a),
        }
        Ok(())
    }

    /// The declared counts checked against what was read, and the mesh assembled.
    fn finish(self, file: &Path) -> Result<(Mesh, Fields), ParseError> {
        let c = &self.c;
        let (npoints, pts) = self
            .points
            .ok_or_else(|| ParseError::new(file, Location::File, "no POINTS section"))?;
        let (ncells, cline) = self.ncells_decl.unwrap_or((0, c.line));
        if self.cells.types.len() != ncells {
            return Err(c.err_line(
                cline,
                format!(
                    "CELLS declares {ncells} cells but CELL_TYPES lists {}",
                    self.cells.types.len()
                ),
            ));
        }
        for (arrays, what, n) in
            [(&self.pdata, "POINT_DATA", npoints), (&self.cdata, "CELL_DATA", ncells)]
        {
            if let Some(a) = arrays.iter().find(|a| Some(a.data.len()) != a.ncomp.checked_mul(n)) {
                return Err(ParseError::new(
                    file,
                    a.loc,
                    format!(
                        "{what} array '{}' has {} values; {n} tuples of {} expected",
                        a.name,
                        a.data.len(),
                        a.ncomp
                    ),
                ));
            }
        }
        assemble(file, npoints, &pts, &self.cells, self.pdata, self.cdata)
    }
}

/// The components and data type of an attribute keyword's array, read from its header.
fn attribute_shape<'a>(
    c: &mut Cursor<'a>,
    kw_up: &str,
    line: usize,
) -> Result<(usize, &'a str), ParseError> {
    Ok(match kw_up {
        "SCALARS" => {
            let (ty, _) = c.expect_token("the data type")?;
            let rest = c.rest_of_line();
            let nc = match rest.split_whitespace().next() {
                None => 1,
                Some(t) => t.parse().map_err(|_| {
                    c.err_line(line, format!("expected the number of components, found '{t}'"))
                })?,
            };
            if c.peek_token() == Some("LOOKUP_TABLE") {
                c.token();
                c.expect_token("the lookup table name")?;
            }
            (nc, ty)
        }
        "VECTORS" | "NORMALS" => (3, c.expect_token("the data type")?.0),
        "TENSORS" => (9, c.expect_token("the data type")?.0),
        "TEXTURE_COORDINATES" => (c.count("the dimension")?.0, c.expect_token("the data type")?.0),
        "COLOR_SCALARS" => {
            (c.count("the number of values")?.0, if c.binary { "unsigned_char" } else { "float" })
        }
        _ => (1, c.expect_token("the data type")?.0),
    })
}

fn ints(d: Data, c: &Cursor<'_>, line: usize, what: &str) -> Result<Vec<i64>, ParseError> {
    match d {
        Data::I(v) => Ok(v),
        Data::F(_) => Err(c.err_line(line, format!("{what} must have an integer type"))),
    }
}

/// Writes a legacy VTK 4.2 ASCII unstructured grid with ids, sets and fields.
pub fn write(w: &mut dyn Write, mesh: &Mesh, fields: &Fields) -> io::Result<()> {
    check_for_write(mesh, fields)?;
    let (nn, ne) = (mesh.nodes.len(), mesh.elements.len());
    writeln!(w, "# vtk DataFile Version 4.2")?;
    // The title line: 3D Slicer reads the frame from `SPACE=` there (a line of at most 256
    // characters).
    match fields.field_data.iter().find(|(name, _)| name == "SPACE") {
        Some((_, space))
            if space.len() <= 16 && space.chars().all(|c| c.is_ascii_alphanumeric()) =>
        {
            writeln!(w, "brainshift output. SPACE={space}")?
        }
        _ => writeln!(w, "brainshift output")?,
    }
    writeln!(w, "ASCII")?;
    writeln!(w, "DATASET UNSTRUCTURED_GRID")?;
    writeln!(w, "POINTS {nn} double")?;
    for p in &mesh.nodes {
        writeln!(w, "{:?} {:?} {:?}", p.x, p.y, p.z)?;
    }
    let size: usize = mesh.elements.iter().map(|e| 1 + e.nodes().len()).sum();
    writeln!(w, "CELLS {ne} {size}")?;
    for e in &mesh.elements {
        write!(w, "{}", e.nodes().len())?;
        for n in e.nodes() {
            write!(w, " {n}")?;
        }
        writeln!(w)?;
    }
    writeln!(w, "CELL_TYPES {ne}")?;
    for e in &mesh.elements {
        writeln!(
            w,
            "{}",
            match e.kind() {
                ElementKind::Tet4 => 10,
                ElementKind::Hex8 => 12,
            }
        )?;
    }
    let sections = [
        ("POINT_DATA", nn, &fields.point, "node_id", &mesh.node_ids, "nset:", &mesh.node_sets),
        (
            "CELL_DATA",
            ne,
            &fields.cell,
            "element_id",
            &mesh.element_ids,
            "elset:",
            &mesh.element_sets,
        ),
    ];
    for (kw, n, list, id_name, ids, prefix, sets) in sections {
        writeln!(w, "{kw} {n}")?;
        writeln!(w, "FIELD FieldData {}", list.len() + 1 + sets.len())?;
        writeln!(w, "{id_name} 1 {n} unsigned_long")?;
        for id in ids {
            writeln!(w, "{id}")?;
        }
        for (name, members) in sets {
            writeln!(w, "{} 1 {n} unsigned_char", encode_name(&format!("{prefix}{name}")))?;
            let mut flags = vec![0u8; n];
            for &i in members {
                flags[i] = 1;
            }
            for f in flags {
                writeln!(w, "{f}")?;
            }
        }
        for f in list {
            writeln!(w, "{} {} {n} double", encode_name(&f.name), f.components)?;
            for tuple in f.values.chunks(f.components) {
                let mut sep = "";
                for v in tuple {
                    write!(w, "{sep}{v:?}")?;
                    sep = " ";
                }
                writeln!(w)?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_frame_travels_in_the_title_line_as_slicer_reads_it() {
        let mesh = crate::structured::box_mesh(1, 1.0, true);
        let fields =
            Fields { field_data: vec![("SPACE".into(), "LPS".into())], ..Fields::default() };
        let mut bytes = Vec::new();
        write(&mut bytes, &mesh, &fields).unwrap();
        let text = String::from_utf8(bytes.clone()).unwrap();
        assert_eq!(text.lines().nth(1), Some("brainshift output. SPACE=LPS"));
        let (_, back) = read(&bytes, Path::new("t.vtk")).unwrap();
        assert_eq!(back.field_data, fields.field_data);
        // Slicer's own header ("3D Slicer output. SPACE=RAS") reads the same way.
        let slicer = text.replace("brainshift output. SPACE=LPS", "3D Slicer output. SPACE=RAS");
        let (_, back) = read(slicer.as_bytes(), Path::new("t.vtk")).unwrap();
        assert_eq!(back.field_data, vec![("SPACE".to_string(), "RAS".to_string())]);
    }

    #[test]
    fn names_round_trip_through_percent_encoding() {
        for s in ["a b", "100%", "nset:LEFT SIDE", "ü", "x\ty"] {
            assert_eq!(decode_name(&encode_name(s)), s);
            assert!(!encode_name(s).contains(char::is_whitespace));
        }
    }
}
