//! Helpers every xtask driver shares: where the repository is, writing files, splicing a
//! generated block between markers of a document, escaping table cells.

use std::path::{Path, PathBuf};

/// The repository's root folder.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Writes `text` to `path`, creating its folder.
pub fn write(path: &Path, text: &str) -> Result<(), String> {
    if let Some(d) = path.parent() {
        std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))
}

/// Replaces the text between `<!-- NAME:begin -->` and `<!-- NAME:end -->` in `path`.
pub fn replace_block(path: &Path, name: &str, body: &str) -> Result<(), String> {
    let doc = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let (begin, end) = (format!("<!-- {name}:begin -->"), format!("<!-- {name}:end -->"));
    let (Some(a), Some(b)) = (doc.find(&begin), doc.find(&end)) else {
        return Err(format!("{}: missing the {begin} / {end} markers", path.display()));
    };
    write(path, &format!("{}{begin}\n{body}{}", &doc[..a], &doc[b..]))
}

/// A Markdown table cell: `|` escaped.
pub fn escape_cell(s: &str) -> String {
    s.replace('|', "\\|")
}
