//! The seed inputs of every reader: small fixtures, and the writers' outputs of a small mesh
//! and surface.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use bs_mesh::io::{inp, obj, off, stl, vtk, vtu};

use crate::reader::Reader;

/// Seed files larger than this are left out: they slow the fuzzer without covering more.
const MAX_SEED_BYTES: u64 = 100_000;

/// The seed inputs of every reader: small fixtures, plus files the writers make (every VTU
/// encoding, ASCII and binary STL) so each code path has a valid start.
pub fn seeds() -> Result<BTreeMap<Reader, Vec<Vec<u8>>>, String> {
    let root = crate::root();
    let mut seeds: BTreeMap<Reader, Vec<Vec<u8>>> = BTreeMap::new();
    let mut scan = |dir: &Path| -> Result<(), String> {
        let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let mut paths: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
        paths.sort();
        for p in paths {
            let Some(reader) = Reader::of_path(&p) else { continue };
            let len = std::fs::metadata(&p).map(|m| m.len()).unwrap_or(u64::MAX);
            if len <= MAX_SEED_BYTES {
                let bytes = std::fs::read(&p).map_err(|e| format!("{}: {e}", p.display()))?;
                seeds.entry(reader).or_default().push(bytes);
            }
        }
        Ok(())
    };
    for dir in ["basic", "readers", "bad", "cube", "ellipsoid", "sphere-shell", "mni152"] {
        scan(&root.join("fixtures").join(dir))?;
    }
    // Derived seeds: the writers' outputs of a small mesh and surface.
    let sphere =
        std::fs::read(root.join("fixtures/basic/sphere.vtu")).map_err(|e| e.to_string())?;
    let (mesh, fields) = vtu::read(&sphere, Path::new("sphere.vtu")).map_err(|e| e.to_string())?;
    let shell = std::fs::read(root.join("fixtures/basic/shell.off")).map_err(|e| e.to_string())?;
    let surface = off::read(&shell, Path::new("shell.off")).map_err(|e| e.to_string())?;
    let mut write = |reader: Reader, f: &dyn Fn(&mut Vec<u8>) -> std::io::Result<()>| {
        let mut out = Vec::new();
        if f(&mut out).is_ok() {
            seeds.entry(reader).or_default().push(out);
        }
    };
    write(Reader::Vtu, &|w| vtu::write(w, &mesh, &fields, vtu::Encoding::Inline));
    write(Reader::Vtu, &|w| vtu::write(w, &mesh, &fields, vtu::Encoding::Appended));
    write(Reader::Vtk, &|w| vtk::write(w, &mesh, &fields));
    write(Reader::Inp, &|w| inp::write(w, &mesh));
    write(Reader::Stl, &|w| stl::write_ascii(w, &surface));
    write(Reader::Stl, &|w| stl::write_binary(w, &surface));
    write(Reader::Obj, &|w| obj::write(w, &surface));
    write(Reader::Off, &|w| off::write(w, &surface));
    for r in Reader::ALL {
        if seeds.get(&r).is_none_or(|s| s.is_empty()) {
            return Err(format!("no seed input for the {} reader", r.name()));
        }
    }
    Ok(seeds)
}
