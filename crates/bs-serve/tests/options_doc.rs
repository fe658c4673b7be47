//! The options are declared once (`bs_serve::Options`, clap); docs/operating-room.md names
//! every one of them and no other.

use clap::CommandFactory;

#[test]
fn the_operating_room_page_lists_exactly_the_declared_options() {
    let page = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../docs/operating-room.md"
    ))
    .expect("docs/operating-room.md");
    let cmd = bs_serve::Command::command();
    let declared: Vec<String> = cmd
        .get_arguments()
        .filter_map(|a| a.get_long())
        .map(|l| format!("--{l}"))
        .filter(|l| l != "--help")
        .collect();
    let options = page
        .lines()
        .skip_while(|l| !l.starts_with("Options:"))
        .take_while(|l| !l.trim().is_empty())
        .collect::<Vec<_>>()
        .join(" ");
    assert!(!options.is_empty(), "docs/operating-room.md has no 'Options:' paragraph");
    for o in &declared {
        assert!(
            options.contains(&format!("`{o}")),
            "{o} is declared but not in the page's options"
        );
    }
    let mentioned: Vec<&str> = options
        .split('`')
        .filter(|w| w.starts_with("--"))
        .map(|w| w.split_whitespace().next().unwrap_or(w))
        .collect();
    for m in mentioned {
        assert!(declared.iter().any(|d| d == m), "{m} is in the page but not an option");
    }
}
