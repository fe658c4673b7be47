//! Mesh file formats.
//!
//! Volume meshes: Abaqus `.inp`, Gmsh `.msh` (4.1 and 2.2, ASCII or binary), VTK legacy `.vtk` and
//! VTU `.vtu` unstructured grids. Surfaces: STL (ASCII and binary), OBJ, OFF. Point clouds
//! ([`points::read_points`]): CSV, PLY, VTK legacy and XML polydata, and the vertices of the
//! surface formats.
//!
//! Every parser works on bytes already in memory (so tests can feed truncated and mutated
//! input) and reports a [`ParseError`] naming the file, the line (text formats) or byte
//! offset (binary data) and what was expected. No input makes a parser panic.
//!
//! Writers never leave a half-written file behind: [`write_atomic`] writes a temporary file
//! beside the target and renames it into place only when everything was written.

use std::fmt;
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::{Mesh, TriSurface};

pub mod inp;
pub mod msh;
pub mod obj;
pub mod off;
pub mod ply;
pub mod points;
pub mod stl;
pub mod vtk;
pub mod vtu;

/// Where in a file a parse error happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Location {
    /// 1-based line number of a text file.
    Line(usize),
    /// 0-based byte offset (binary content).
    Byte(usize),
    /// The whole file (e.g. a missing section).
    File,
}

/// A malformed file: where and what was expected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub struct ParseError {
    /// The file being read (as given by the caller).
    pub file: PathBuf,
    /// Where the problem is.
    pub location: Location,
    /// What was found and what was expected, phrased for a user.
    pub message: String,
}

impl ParseError {
    /// A parse error at `location` of `file`.
    pub fn new(file: &Path, location: Location, message: impl Into<String>) -> Self {
        ParseError { file: file.to_path_buf(), location, message: message.into() }
    }
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let file = self.file.display();
        match self.location {
            Location::Line(l) => write!(f, "{file}:{l}: {}", self.message),
            Location::Byte(b) => write!(f, "{file}: at byte {b}: {}", self.message),
            Location::File => write!(f, "{file}: {}", self.message),
        }
    }
}

/// Errors of reading or writing mesh files.
#[derive(Debug, thiserror::Error)]
pub enum MeshIoError {
    /// The operating system refused (missing file, permissions, full disk).
    #[error("{}: {source}", file.display())]
    Io {
        /// The file.
        file: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The file content is malformed.
    #[error(transparent)]
    Parse(#[from] ParseError),
    /// The extension names no supported format, or the format cannot hold what was asked.
    #[error("{}: {message}", file.display())]
    Unsupported {
        /// The file.
        file: PathBuf,
        /// What is unsupported and what to use instead.
        message: String,
    },
}

/// Mesh file formats known to brainshift.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Abaqus input deck (`.inp`).
    Inp,
    /// Gmsh mesh (`.msh`, versions 4.1 and 2.2, ASCII or binary).
    Msh,
    /// VTK legacy unstructured grid (`.vtk`).
    Vtk,
    /// VTK XML unstructured grid (`.vtu`).
    Vtu,
    /// STL triangle soup (`.stl`, ASCII or binary).
    Stl,
    /// Wavefront OBJ (`.obj`).
    Obj,
    /// Object File Format (`.off`).
    Off,
}

impl Format {
    /// All formats, for help texts.
    pub const ALL: [Format; 7] =
        [Format::Inp, Format::Msh, Format::Vtk, Format::Vtu, Format::Stl, Format::Obj, Format::Off];

    /// The format named by a path's extension (case-insensitive).
    pub fn from_path(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "inp" => Format::Inp,
            "msh" => Format::Msh,
            "vtk" => Format::Vtk,
            "vtu" => Format::Vtu,
            "stl" => Format::Stl,
            "obj" => Format::Obj,
            "off" => Format::Off,
            _ => return None,
        })
    }

    /// The usual file extension, without the dot.
    pub const fn extension(self) -> &'static str {
        match self {
            Format::Inp => "inp",
            Format::Msh => "msh",
            Format::Vtk => "vtk",
            Format::Vtu => "vtu",
            Format::Stl => "stl",
            Format::Obj => "obj",
            Format::Off => "off",
        }
    }

    /// Whether the format holds volume meshes (otherwise triangle surfaces).
    pub const fn is_volume(self) -> bool {
        matches!(self, Format::Inp | Format::Msh | Format::Vtk | Format::Vtu)
    }
}

/// A named array attached to points or cells (e.g. displacement, von Mises stress).
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// Array name as shown in ParaView.
    pub name: String,
    /// Components per tuple (1 scalar, 3 vector).
    pub components: usize,
    /// `components × count` values, tuple-major.
    pub values: Vec<f64>,
}

impl Field {
    /// A field; `values.len()` must be a multiple of `components`.
    pub fn new(name: impl Into<String>, components: usize, values: Vec<f64>) -> Self {
        Field { name: name.into(), components, values }
    }
}

/// Point and cell data that travel with a mesh in VTU/VTK files.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Fields {
    /// Per-node arrays.
    pub point: Vec<Field>,
    /// Per-element arrays.
    pub cell: Vec<Field>,
    /// Named strings about the whole dataset (VTU `FieldData` String arrays, e.g. `SPACE`
    /// = `RAS`, the anatomical frame of the coordinates). Written and read by the VTU format;
    /// the legacy VTK format holds `SPACE` alone, as `SPACE=RAS` in its title line (3D
    /// Slicer's convention for legacy files).
    pub field_data: Vec<(String, String)>,
}

/// What a file holds.
#[derive(Debug, Clone, PartialEq)]
pub enum MeshFile {
    /// A volume mesh (with any point/cell data the file had).
    Volume(Mesh, Fields),
    /// A triangle surface.
    Surface(TriSurface),
}

fn read_bytes(path: &Path) -> Result<Vec<u8>, MeshIoError> {
    std::fs::read(path).map_err(|source| MeshIoError::Io { file: path.to_path_buf(), source })
}

fn unknown_format(path: &Path) -> MeshIoError {
    MeshIoError::Unsupported {
        file: path.to_path_buf(),
        message: "unknown file extension; use one of .inp, .msh, .vtk, .vtu (volume) or .stl, \
                  .obj, .off (surface)"
            .into(),
    }
}

/// Reads any supported file, dispatching on the extension.
pub fn read(path: &Path) -> Result<MeshFile, MeshIoError> {
    let format = Format::from_path(path).ok_or_else(|| unknown_format(path))?;
    let bytes = read_bytes(path)?;
    Ok(match format {
        Format::Inp => MeshFile::Volume(inp::read(&bytes, path)?, Fields::default()),
        Format::Msh => MeshFile::Volume(msh::read(&bytes, path)?, Fields::default()),
        Format::Vtk => {
            let (m, f) = vtk::read(&bytes, path)?;
            MeshFile::Volume(m, f)
        }
        Format::Vtu => {
            let (m, f) = vtu::read(&bytes, path)?;
            MeshFile::Volume(m, f)
        }
        Format::Stl => MeshFile::Surface(stl::read(&bytes, path)?),
        Format::Obj => MeshFile::Surface(obj::read(&bytes, path)?),
        Format::Off => MeshFile::Surface(off::read(&bytes, path)?),
    })
}

/// Reads a volume mesh (`.inp`, `.msh`, `.vtk`, `.vtu`).
pub fn read_mesh(path: &Path) -> Result<Mesh, MeshIoError> {
    match read(path)? {
        MeshFile::Volume(m, _) => Ok(m),
        MeshFile::Surface(_) => Err(MeshIoError::Unsupported {
            file: path.to_path_buf(),
            message: "this is a surface format; a volume mesh (.inp, .msh, .vtk, .vtu) is needed \
                      here"
                .into(),
        }),
    }
}

/// Reads a triangle surface (`.stl`, `.obj`, `.off`).
pub fn read_surface(path: &Path) -> Result<TriSurface, MeshIoError> {
    match read(path)? {
        MeshFile::Surface(s) => Ok(s),
        MeshFile::Volume(..) => Err(MeshIoError::Unsupported {
            file: path.to_path_buf(),
            message: "this is a volume format; a triangle surface (.stl, .obj, .off) is needed \
                      here"
                .into(),
        }),
    }
}

/// Writes a volume mesh with point and cell data; the format comes from the extension
/// (`.vtu` binary appended, `.vtk` legacy ASCII, `.inp` Abaqus without the fields).
pub fn write_mesh(path: &Path, mesh: &Mesh, fields: &Fields) -> Result<(), MeshIoError> {
    match Format::from_path(path) {
        Some(Format::Vtu) => {
            write_atomic(path, |w| vtu::write(w, mesh, fields, vtu::Encoding::Appended))
        }
        Some(Format::Vtk) => write_atomic(path, |w| vtk::write(w, mesh, fields)),
        // Abaqus decks hold no point or cell data: the fields are not written.
        Some(Format::Inp) => write_atomic(path, |w| inp::write(w, mesh)),
        Some(f) => Err(MeshIoError::Unsupported {
            file: path.to_path_buf(),
            message: format!(
                "writing volume meshes as .{} is not supported; use .vtu, .vtk or .inp",
                f.extension()
            ),
        }),
        None => Err(unknown_format(path)),
    }
}

/// Like [`write_mesh`], and a `.vtu` also carries the field-data string `SPACE` = `space`
/// (e.g. `"RAS"`), a `.vtk` `SPACE=RAS` in its title line: the coordinate frame 3D Slicer
/// reads from each; `.inp` has no place for it.
pub fn write_mesh_in_space(
    path: &Path,
    mesh: &Mesh,
    fields: &Fields,
    space: &str,
) -> Result<(), MeshIoError> {
    let mut fields = fields.clone();
    fields.field_data.retain(|(name, _)| name != "SPACE");
    fields.field_data.push(("SPACE".into(), space.into()));
    write_mesh(path, mesh, &fields)
}

/// Writes a triangle surface as `.off` or `.stl` (binary), chosen by extension.
pub fn write_surface(path: &Path, surface: &TriSurface) -> Result<(), MeshIoError> {
    match Format::from_path(path) {
        Some(Format::Off) => write_atomic(path, |w| off::write(w, surface)),
        Some(Format::Stl) => write_atomic(path, |w| stl::write_binary(w, surface)),
        Some(Format::Obj) => write_atomic(path, |w| obj::write(w, surface)),
        Some(f) => Err(MeshIoError::Unsupported {
            file: path.to_path_buf(),
            message: format!(
                "writing surfaces as .{} is not supported; use .off, .stl or .obj",
                f.extension()
            ),
        }),
        None => Err(unknown_format(path)),
    }
}

/// Writes `path` through a temporary file in the same directory, renamed into place only
/// after `write` succeeded and the data was flushed: readers never see a partial file and a
/// failed write leaves any previous file untouched.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<(), MeshIoError> {
    bs_atomic::write_atomic(path, write)
        .map_err(|source| MeshIoError::Io { file: path.to_path_buf(), source })
}

/// Writers refuse a surface whose triangles point past its vertices (an `InvalidInput`
/// error naming the triangle) instead of writing a file no reader accepts.
pub(crate) fn require_indices_in_range(s: &TriSurface) -> std::io::Result<()> {
    let nv = s.vertices.len();
    match s.triangles.iter().position(|t| t.iter().any(|&i| i >= nv)) {
        Some(t) => Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("triangle {t} refers to a vertex beyond the {nv} vertices"),
        )),
        None => Ok(()),
    }
}

/// Line-oriented text cursor shared by the text parsers: yields `(line_number, line)` with
/// 1-based numbers and keeps the file name for errors.
#[derive(Debug)]
pub(crate) struct Lines<'a> {
    file: &'a Path,
    lines: std::iter::Peekable<std::iter::Enumerate<std::str::Lines<'a>>>,
    last: usize,
}

impl<'a> Lines<'a> {
    /// Decodes `bytes` as UTF-8 (error with the byte offset otherwise), skipping a leading
    /// UTF-8 byte-order mark as Windows editors write it.
    pub(crate) fn new(bytes: &'a [u8], file: &'a Path) -> Result<Self, ParseError> {
        let skipped = bytes.len() - strip_bom(bytes).len();
        let text = std::str::from_utf8(&bytes[skipped..]).map_err(|e| {
            ParseError::new(
                file,
                Location::Byte(skipped + e.valid_up_to()),
                "the file is not valid UTF-8 text",
            )
        })?;
        Ok(Lines { file, lines: text.lines().enumerate().peekable(), last: 0 })
    }

    /// The next line with its 1-based number.
    pub(crate) fn next_line(&mut self) -> Option<(usize, &'a str)> {
        let (i, l) = self.lines.next()?;
        self.last = i + 1;
        Some((i + 1, l))
    }

    /// The next line without consuming it.
    pub(crate) fn peek(&mut self) -> Option<(usize, &'a str)> {
        self.lines.peek().map(|&(i, l)| (i + 1, l))
    }

    /// An error at line `line`.
    pub(crate) fn error(&self, line: usize, message: impl Into<String>) -> ParseError {
        ParseError::new(self.file, Location::Line(line), message)
    }

    /// An error at the end of the file (something was missing).
    pub(crate) fn eof_error(&self, expected: &str) -> ParseError {
        ParseError::new(
            self.file,
            Location::Line(self.last.max(1)),
            format!("unexpected end of file: expected {expected}"),
        )
    }

    /// The file name.
    pub(crate) fn file(&self) -> &'a Path {
        self.file
    }
}

/// The UTF-8 byte-order mark some editors put at the start of text files.
pub(crate) const UTF8_BOM: &[u8] = b"\xEF\xBB\xBF";

/// `bytes` without a leading UTF-8 byte-order mark (unchanged when there is none).
pub(crate) fn strip_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(UTF8_BOM).unwrap_or(bytes)
}

/// Parses one whitespace- or comma-separated field as `T`, with an error naming the line and
/// what was expected.
pub(crate) fn parse_field<T: std::str::FromStr>(
    file: &Path,
    line: usize,
    field: &str,
    what: &str,
) -> Result<T, ParseError> {
    field.trim().parse::<T>().map_err(|_| {
        ParseError::new(
            file,
            Location::Line(line),
            format!("expected {what}, found '{}'", field.trim()),
        )
    })
}
