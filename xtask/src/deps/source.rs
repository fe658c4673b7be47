//! A Rust source file reduced to what the module graph needs: the tokens of its code
//! (comments, string and character literals removed; `#[cfg(test)]` items removed), the
//! intra-doc link targets of its doc comments, and the child modules it declares test-only.
//!
//! Not a Rust parser: a tokenizer that knows where comments, literals and items end, which is
//! all that finding `crate::`, `super::` and `self::` paths needs.

/// One token of code.
#[derive(Debug, Clone, PartialEq)]
pub enum Tok {
    /// An identifier or keyword (`crate`, `use`, `kernels`, …); raw identifiers lose `r#`.
    Ident(String),
    /// `::`.
    PathSep,
    /// Any other character (`{`, `}`, `,`, `*`, `;`, `#`, …); literals become `'0'`.
    Punct(char),
}

/// A token and the line (from 1) it starts on.
#[derive(Debug, Clone, PartialEq)]
pub struct Token {
    /// The token.
    pub tok: Tok,
    /// Its line.
    pub line: usize,
}

/// What the module graph reads from one file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Source {
    /// The code's tokens, without `#[cfg(test)]` items.
    pub tokens: Vec<Token>,
    /// Link targets of the doc comments outside `#[cfg(test)]` items: (line, path) for every
    /// ``[`path`]``, `[text](path)` and `[text]: path` whose path starts with `crate::`,
    /// `super::` or `self::`.
    pub doc_links: Vec<(usize, String)>,
    /// Child modules declared `#[cfg(test)] mod name;`.
    pub test_children: Vec<String>,
}

impl Source {
    /// Reads `text`.
    pub fn parse(text: &str) -> Source {
        let (tokens, docs) = tokenize(text);
        let (tokens, removed, test_children) = without_test_items(tokens);
        let doc_links = docs
            .iter()
            .filter(|(line, _)| !removed.iter().any(|(lo, hi)| line >= lo && line <= hi))
            .flat_map(|(line, doc)| links(doc).into_iter().map(move |l| (*line, l)))
            .collect();
        Source { tokens, doc_links, test_children }
    }
}

/// Characters of an identifier after the first.
fn ident_char(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// Tokens of `text` and its doc comments as (line, text).
fn tokenize(text: &str) -> (Vec<Token>, Vec<(usize, String)>) {
    let c: Vec<char> = text.chars().collect();
    let mut t = Lexer { c: &c, i: 0, line: 1, tokens: Vec::new(), docs: Vec::new() };
    while t.i < c.len() {
        t.step();
    }
    (t.tokens, t.docs)
}

struct Lexer<'a> {
    c: &'a [char],
    i: usize,
    line: usize,
    tokens: Vec<Token>,
    docs: Vec<(usize, String)>,
}

impl Lexer<'_> {
    fn at(&self, k: usize) -> char {
        self.c.get(self.i + k).copied().unwrap_or('\0')
    }

    /// Advances one character, counting lines.
    fn bump(&mut self) {
        if self.at(0) == '\n' {
            self.line += 1;
        }
        self.i += 1;
    }

    fn push(&mut self, tok: Tok, line: usize) {
        self.tokens.push(Token { tok, line });
    }

    fn step(&mut self) {
        let (ch, line) = (self.at(0), self.line);
        match ch {
            c if c.is_whitespace() => self.bump(),
            '/' if self.at(1) == '/' => self.line_comment(),
            '/' if self.at(1) == '*' => self.block_comment(),
            '"' => {
                self.string(false, 0);
                self.push(Tok::Punct('0'), line);
            }
            '\'' => self.quote(),
            ':' if self.at(1) == ':' => {
                self.i += 2;
                self.push(Tok::PathSep, line);
            }
            c if c.is_alphabetic() || c == '_' => self.word(),
            c if c.is_ascii_digit() => {
                while ident_char(self.at(0)) || (self.at(0) == '.' && self.at(1).is_ascii_digit()) {
                    self.bump();
                }
                self.push(Tok::Punct('0'), line);
            }
            c => {
                self.bump();
                self.push(Tok::Punct(c), line);
            }
        }
    }

    /// `//…`: a doc comment (`///`, not `////`; `//!`) is kept.
    fn line_comment(&mut self) {
        let doc = (self.at(2) == '/' && self.at(3) != '/') || self.at(2) == '!';
        let start = self.i;
        while self.i < self.c.len() && self.at(0) != '\n' {
            self.i += 1;
        }
        if doc {
            self.docs.push((self.line, self.c[start + 3..self.i].iter().collect()));
        }
    }

    /// `/* … */`, nested; `/** */` and `/*! */` are doc comments.
    fn block_comment(&mut self) {
        let (line, doc) = (self.line, matches!(self.at(2), '*' | '!') && self.at(3) != '/');
        let start = self.i;
        self.i += 2;
        let mut depth = 1;
        while self.i < self.c.len() && depth > 0 {
            if self.at(0) == '/' && self.at(1) == '*' {
                depth += 1;
                self.i += 2;
            } else if self.at(0) == '*' && self.at(1) == '/' {
                depth -= 1;
                self.i += 2;
            } else {
                self.bump();
            }
        }
        if doc {
            self.docs.push((line, self.c[start..self.i].iter().collect()));
        }
    }

    /// A string from its opening `"` (at the current position); a raw string (no escapes)
    /// ends at a `"` followed by `hashes` `#`.
    fn string(&mut self, raw: bool, hashes: usize) {
        self.i += 1;
        while self.i < self.c.len() {
            match self.at(0) {
                '\\' if !raw => {
                    self.i += 1;
                    self.bump();
                }
                '"' if (1..=hashes).all(|k| self.at(k) == '#') => {
                    self.i += 1 + hashes;
                    return;
                }
                _ => self.bump(),
            }
        }
    }

    /// `'`: a character literal (`'a'`, `'\n'`, `'\u{1F600}'`) or a lifetime or label.
    fn quote(&mut self) {
        let line = self.line;
        if self.at(1) == '\\' {
            self.i += 3;
            while self.i < self.c.len() && self.at(0) != '\'' {
                self.i += 1;
            }
            self.i += 1;
            self.push(Tok::Punct('0'), line);
        } else if self.at(2) == '\'' {
            self.i += 3;
            self.push(Tok::Punct('0'), line);
        } else {
            // A lifetime: its name follows as an identifier, harmless.
            self.i += 1;
        }
    }

    /// An identifier, a raw identifier, or the prefix of a (raw) string literal.
    fn word(&mut self) {
        let line = self.line;
        let start = self.i;
        while ident_char(self.at(0)) {
            self.i += 1;
        }
        let w: String = self.c[start..self.i].iter().collect();
        let raw_prefix = matches!(w.as_str(), "r" | "br" | "cr");
        let str_prefix = matches!(w.as_str(), "b" | "c");
        if (raw_prefix || str_prefix) && self.at(0) == '"' {
            self.string(raw_prefix, 0);
            self.push(Tok::Punct('0'), line);
        } else if raw_prefix && self.at(0) == '#' && matches!(self.at(1), '"' | '#') {
            let mut hashes = 0;
            while self.at(0) == '#' {
                hashes += 1;
                self.i += 1;
            }
            self.string(true, hashes);
            self.push(Tok::Punct('0'), line);
        } else if w == "r" && self.at(0) == '#' && ident_char(self.at(1)) {
            self.i += 1;
            self.word();
        } else if w == "b" && self.at(0) == '\'' {
            self.quote();
        } else {
            self.push(Tok::Ident(w), line);
        }
    }
}

/// Whether `toks[i..]` starts with `# [ cfg ( test ) ]`.
fn is_cfg_test(toks: &[Token], i: usize) -> bool {
    let want = ["#", "[", "cfg", "(", "test", ")", "]"];
    want.iter().enumerate().all(|(k, w)| match toks.get(i + k).map(|t| &t.tok) {
        Some(Tok::Ident(s)) => s == w,
        Some(Tok::Punct(c)) => w.len() == 1 && w.starts_with(*c),
        _ => false,
    })
}

fn is_punct(toks: &[Token], i: usize, c: char) -> bool {
    matches!(toks.get(i), Some(Token { tok: Tok::Punct(p), .. }) if *p == c)
}

fn is_ident(toks: &[Token], i: usize, w: &str) -> bool {
    matches!(toks.get(i), Some(Token { tok: Tok::Ident(s), .. }) if s == w)
}

/// Index after the bracketed group opening at `i` (`(`, `[` or `{`).
fn skip_group(toks: &[Token], mut i: usize) -> usize {
    let mut depth = 0i32;
    while i < toks.len() {
        match toks[i].tok {
            Tok::Punct('(' | '[' | '{') => depth += 1,
            Tok::Punct(')' | ']' | '}') => {
                depth -= 1;
                if depth == 0 {
                    return i + 1;
                }
            }
            _ => {}
        }
        i += 1;
    }
    i
}

/// Index after the item starting at `i`: at its `;` or after its first `{ … }` at depth 0.
fn skip_item(toks: &[Token], mut i: usize) -> usize {
    while i < toks.len() {
        match toks[i].tok {
            Tok::Punct(';') => return i + 1,
            Tok::Punct('{') => return skip_group(toks, i),
            Tok::Punct('(' | '[') => i = skip_group(toks, i),
            _ => i += 1,
        }
    }
    i
}

/// The tokens without the items under `#[cfg(test)]`, the line ranges removed, and the test
/// child modules declared `mod name;`.
fn without_test_items(toks: Vec<Token>) -> (Vec<Token>, Vec<(usize, usize)>, Vec<String>) {
    let mut out = Vec::with_capacity(toks.len());
    let (mut removed, mut children) = (Vec::new(), Vec::new());
    let mut i = 0;
    while i < toks.len() {
        if !is_cfg_test(&toks, i) {
            out.push(toks[i].clone());
            i += 1;
            continue;
        }
        let start = i;
        i += 7;
        while is_punct(&toks, i, '#') {
            i = skip_group(&toks, i + 1);
        }
        let mut k = i;
        if is_ident(&toks, k, "pub") {
            k += 1;
            if is_punct(&toks, k, '(') {
                k = skip_group(&toks, k);
            }
        }
        if is_ident(&toks, k, "mod")
            && is_punct(&toks, k + 2, ';')
            && let Some(Tok::Ident(name)) = toks.get(k + 1).map(|t| &t.tok)
        {
            children.push(name.clone());
        }
        i = skip_item(&toks, i);
        let last = toks.get(i.saturating_sub(1)).map_or(usize::MAX, |t| t.line);
        removed.push((toks[start].line, last));
    }
    (out, removed, children)
}

/// Link targets in one doc comment that start with `crate::`, `super::` or `self::`.
fn links(doc: &str) -> Vec<String> {
    let mut out = Vec::new();
    let candidates = doc
        .match_indices("[`")
        .map(|(k, _)| k + 2)
        .chain(doc.match_indices("](").map(|(k, _)| k + 2))
        .chain(doc.match_indices("]: ").map(|(k, _)| k + 3));
    for start in candidates {
        let path: String =
            doc[start..].chars().take_while(|&c| ident_char(c) || c == ':').collect();
        let rest = &doc[start + path.len()..];
        let closed = rest.starts_with("`]") || rest.starts_with(')') || rest.trim().is_empty();
        let rooted = ["crate::", "super::", "self::"].iter().any(|p| path.starts_with(p));
        if rooted && closed {
            out.push(path.trim_end_matches(':').to_string());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn idents(s: &Source) -> Vec<String> {
        s.tokens
            .iter()
            .filter_map(|t| match &t.tok {
                Tok::Ident(w) => Some(w.clone()),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn comments_and_literals_hide_their_contents() {
        let s = Source::parse(
            "// crate::hid_a::x\nlet s = \"crate::hid_b::y \\\" crate::hid_c\";\n/* crate::hid_d /* \
             nested */ crate::hid_e */ let r = r#\"crate::hid_f \"# ; let c = '\"'; let l: &'lt \
             str = b\"crate::hid_g\";\nlet ch = '\\u{7b}'; let q = '\\''; use crate::h;",
        );
        let words = idents(&s);
        for hidden in ["hid_a", "hid_b", "hid_c", "hid_d", "hid_e", "hid_f", "hid_g"] {
            assert!(!words.contains(&hidden.to_string()), "{hidden} leaked: {words:?}");
        }
        assert!(words.ends_with(&["use".into(), "crate".into(), "h".into()]), "{words:?}");
        // A lifetime's name reads as an identifier (harmless).
        assert!(words.contains(&"lt".to_string()), "{words:?}");
        let line_of_h = s.tokens.iter().find(|t| t.tok == Tok::Ident("h".into())).unwrap().line;
        assert_eq!(line_of_h, 4);
    }

    #[test]
    fn test_items_are_removed_and_test_children_listed() {
        let s = Source::parse(
            "use crate::kept;\n#[cfg(test)]\nmod tests {\n    use crate::gone;\n    fn f() { \
             let x = \"}\"; }\n}\n#[cfg(test)]\n#[allow(dead_code)]\npub(crate) mod fixtures;\n\
             #[cfg(test)]\nuse crate::also_gone;\nfn after() {}\n/// [`crate::doc_kept`]\n",
        );
        let words = idents(&s);
        assert!(words.contains(&"kept".to_string()) && words.contains(&"after".to_string()));
        assert!(!words.contains(&"gone".to_string()), "{words:?}");
        assert!(!words.contains(&"also_gone".to_string()), "{words:?}");
        assert_eq!(s.test_children, vec!["fixtures".to_string()]);
        assert_eq!(s.doc_links, vec![(13, "crate::doc_kept".to_string())]);
    }

    #[test]
    fn doc_links_are_read_in_every_form() {
        let s = Source::parse(
            "//! See [`crate::solve::prepare`], [the cycle](super::cycle) and [`Model`].\n\
             /// [local]: self::inner::Thing\n/// Plain `crate::not_a_link` in code.\nfn f() {}",
        );
        let paths: Vec<&str> = s.doc_links.iter().map(|(_, p)| p.as_str()).collect();
        assert_eq!(paths, ["crate::solve::prepare", "super::cycle", "self::inner::Thing"]);
    }
}
