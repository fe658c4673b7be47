//! docs/scene.md, the scene reference: every TOML block on it is a complete scene that
//! parses and passes the checks scene text gets (`Scene::parse`), and every key the
//! reference block shows commented out parses too when uncommented on its own.

use std::path::Path;

use bs_scene::Scene;

fn page() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/scene.md");
    std::fs::read_to_string(path).expect("docs/scene.md")
}

/// The ```toml blocks of a Markdown page, with the line each starts on.
fn toml_blocks(text: &str) -> Vec<(usize, String)> {
    let mut blocks = Vec::new();
    let mut current: Option<(usize, String)> = None;
    for (i, line) in text.lines().enumerate() {
        match (&mut current, line.trim_end()) {
            (None, "```toml") => current = Some((i + 2, String::new())),
            (Some(_), "```") => blocks.push(current.take().unwrap()),
            (Some((_, b)), l) => {
                b.push_str(l);
                b.push('\n');
            }
            (None, _) => {}
        }
    }
    assert!(current.is_none(), "an unclosed ```toml block");
    blocks
}

#[test]
fn every_scene_on_the_reference_page_parses() {
    let blocks = toml_blocks(&page());
    assert!(blocks.len() >= 3, "{} blocks", blocks.len());
    for (line, block) in &blocks {
        if let Err(e) = Scene::parse(block) {
            panic!("docs/scene.md, the block at line {line}: {e}");
        }
    }
}

/// The first block's commented keys, put in place one at a time (a commented table with
/// its commented keys as a whole): the alternatives the reference names are keys and tables
/// the parser knows. An uncommented alternative may clash with the key it stands beside
/// (two loads on one boundary): that is an error the parser names, not an unknown key.
#[test]
fn the_reference_blocks_commented_keys_are_keys_the_parser_knows() {
    let blocks = toml_blocks(&page());
    let (start, reference) = (blocks[0].0, &blocks[0].1);
    let lines: Vec<&str> = reference.lines().collect();
    let key_of = |l: &str| -> Option<String> {
        let rest = l.strip_prefix("# ")?;
        if rest.starts_with('[') {
            return Some(rest.split_whitespace().next()?.to_string());
        }
        let (key, _) = rest.split_once(" = ")?;
        key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_').then(|| key.to_string())
    };
    let mut tried = 0;
    let mut i = 0;
    while i < lines.len() {
        let Some(key) = key_of(lines[i]) else {
            i += 1;
            continue;
        };
        // A commented table takes the commented lines after it, up to the next table.
        let mut end = i + 1;
        if key.starts_with('[') {
            while end < lines.len()
                && lines[end].starts_with('#')
                && !key_of(lines[end]).is_some_and(|k| k.starts_with('['))
            {
                end += 1;
            }
        }
        let mut edited: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
        for l in &mut edited[i..end] {
            *l = l.strip_prefix("# ").unwrap_or(l).to_string();
        }
        if let Err(e) = Scene::parse(&edited.join("\n")) {
            assert!(
                !e.contains("unknown field")
                    && !e.contains("unknown variant")
                    && !e.contains("parse error"),
                "docs/scene.md reference block, line {}: `{key}`: {e}",
                start + i
            );
        }
        tried += 1;
        i = end;
    }
    assert!(tried >= 10, "only {tried} commented keys");
}

/// The README's scene is the demo's, `fixtures/mni152/scene.toml`, as it says.
#[test]
fn the_readme_shows_the_demos_scene() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let readme = std::fs::read_to_string(root.join("README.md")).expect("README.md");
    let blocks = toml_blocks(&readme);
    assert_eq!(blocks.len(), 1, "the README shows one scene");
    let shown = Scene::parse(&blocks[0].1).expect("the README's scene parses");
    let demo = std::fs::read_to_string(root.join("fixtures/mni152/scene.toml")).unwrap();
    assert_eq!(shown, Scene::parse(&demo).unwrap());
}
