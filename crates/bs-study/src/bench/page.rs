//! A benchmark's output, printed as it comes and, for the default run, written into its
//! block of `docs/benchmarks.md` (between `<!-- NAME:begin -->` and `<!-- NAME:end -->`),
//! so that the page shows what the command printed last, with the command above it.

use crate::util::{replace_block, root};

/// Prints a line and keeps it for the page: `say!(page, "{x}")` as `println!("{x}")`.
macro_rules! say {
    ($page:expr) => {
        $page.line(String::new())
    };
    ($page:expr, $($fmt:tt)*) => {
        $page.line(format!($($fmt)*))
    };
}
pub(crate) use say;

/// The lines of one benchmark's output and the block they go to.
#[derive(Debug)]
pub struct Page {
    block: &'static str,
    text: String,
}

impl Page {
    /// An empty output for the block `block`.
    pub fn new(block: &'static str) -> Self {
        Page { block, text: String::new() }
    }

    /// Prints `line` and keeps it.
    pub fn line(&mut self, line: String) {
        println!("{line}");
        self.text.push_str(&line);
        self.text.push('\n');
    }

    /// The kept lines as the page shows them: a text block headed by the command.
    pub fn markdown(&self, command: &str) -> String {
        format!("```text\n$ {command}\n{}```\n", self.text)
    }

    /// Writes the kept lines into the block of `docs/benchmarks.md`.
    pub fn write(&self, command: &str) -> Result<(), String> {
        replace_block(&root().join("docs/benchmarks.md"), self.block, &self.markdown(command))?;
        println!("wrote docs/benchmarks.md ({})", self.block);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_kept_under_the_command() {
        let mut p = Page::new("x");
        say!(p, "a {}", 1);
        say!(p);
        say!(p, "b");
        assert_eq!(
            p.markdown("cargo xtask bench x"),
            "```text\n$ cargo xtask bench x\na 1\n\nb\n```\n"
        );
    }
}
