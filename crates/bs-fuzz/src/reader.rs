//! The readers under test, each parsing bytes the way the product reads a file of its kind.

use std::path::{Path, PathBuf};

use bs_mesh::io::{inp, msh, obj, off, stl, vtk, vtu};

/// The readers under test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Reader {
    Inp,
    Msh,
    Vtk,
    Vtu,
    Stl,
    Obj,
    Off,
    Scene,
}

impl Reader {
    pub const ALL: [Reader; 8] = [
        Reader::Inp,
        Reader::Msh,
        Reader::Vtk,
        Reader::Vtu,
        Reader::Stl,
        Reader::Obj,
        Reader::Off,
        Reader::Scene,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Reader::Inp => "inp",
            Reader::Msh => "msh",
            Reader::Vtk => "vtk",
            Reader::Vtu => "vtu",
            Reader::Stl => "stl",
            Reader::Obj => "obj",
            Reader::Off => "off",
            Reader::Scene => "scene",
        }
    }

    pub fn extension(self) -> &'static str {
        match self {
            Reader::Scene => "toml",
            r => r.name(),
        }
    }

    /// The reader of a saved input, from its file name (`<reader>-<n>.<ext>`) or extension.
    pub fn of_path(path: &Path) -> Option<Reader> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Reader::ALL.into_iter().find(|r| r.extension() == ext)
    }

    /// Parses `bytes`; `Ok` or `Err` are both fine, only panics and hangs are findings.
    /// Returns whether the input was accepted.
    pub fn parse(self, bytes: &[u8]) -> bool {
        let file = PathBuf::from(format!("fuzz.{}", self.extension()));
        match self {
            Reader::Inp => inp::read(bytes, &file).is_ok(),
            Reader::Msh => msh::read(bytes, &file).is_ok(),
            Reader::Vtk => vtk::read(bytes, &file).is_ok(),
            Reader::Vtu => vtu::read(bytes, &file).is_ok(),
            Reader::Stl => stl::read(bytes, &file).is_ok(),
            Reader::Obj => obj::read(bytes, &file).is_ok(),
            Reader::Off => off::read(bytes, &file).is_ok(),
            Reader::Scene => bs_scene::scene::Scene::parse(&String::from_utf8_lossy(bytes)).is_ok(),
        }
    }
}
