//! The stability map drawn: one row per experiment, one cell per run, coloured by outcome.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::Cell;
use crate::plot::{Figure, err};
use crate::verdict::Verdict;

/// The map: one row per experiment, one cell per run, coloured by outcome.
pub(super) struct Map<'a> {
    pub(super) cells: &'a [Cell],
}

impl Figure for Map<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let mut rows: Vec<&str> = Vec::new();
        for c in self.cells {
            if !rows.contains(&c.row.as_str()) {
                rows.push(&c.row);
            }
        }
        let cols = rows
            .iter()
            .map(|r| self.cells.iter().filter(|c| c.row == *r).count())
            .max()
            .unwrap_or(1);
        let (w, h) = root.dim_in_pixel();
        let (left, top) = (330i32, 50i32);
        let cw = (w as i32 - left - 10) / cols as i32;
        let rh = ((h as i32 - top - 40) / rows.len().max(1) as i32).min(70);
        root.draw(&Text::new(
            "Stability map: one run per cell (green converged, orange stopped by a guard, red failed silently)",
            (10, 15),
            ("sans-serif", 17),
        ))
        .map_err(err)?;
        for (ri, r) in rows.iter().enumerate() {
            let y = top + ri as i32 * rh;
            let lines = wrap(r, 44);
            for (k, line) in lines.iter().enumerate() {
                let dy = 16 * k as i32 - 8 * (lines.len() as i32 - 1);
                root.draw(&Text::new(line.clone(), (8, y + rh / 2 - 7 + dy), ("sans-serif", 14)))
                    .map_err(err)?;
            }
            for (ci, c) in self.cells.iter().filter(|c| c.row == *r).enumerate() {
                let x = left + ci as i32 * cw;
                let color = match c.verdict {
                    Verdict::Converged => RGBColor(120, 200, 120),
                    Verdict::Guard(_) => RGBColor(240, 170, 80),
                    Verdict::Silent(_) => RGBColor(220, 60, 60),
                    Verdict::External(ref s) if s == "converged" => RGBColor(170, 220, 170),
                    Verdict::External(_) => RGBColor(200, 200, 200),
                };
                root.draw(&Rectangle::new(
                    [(x + 2, y + 2), (x + cw - 2, y + rh - 2)],
                    color.filled(),
                ))
                .map_err(err)?;
                let outcome = match &c.verdict {
                    Verdict::Converged => format!("ok, {} steps", c.steps),
                    other => Verdict::text(other).replace("guard: ", ""),
                };
                let value =
                    if c.ablation { format!("{} (ablation)", c.value) } else { c.value.clone() };
                for (k, line) in [value, outcome, c.note.clone()].iter().enumerate() {
                    let mut line = line.clone();
                    if line.chars().count() > 24 {
                        line = line.chars().take(23).collect::<String>() + "…";
                    }
                    root.draw(&Text::new(line, (x + 6, y + 6 + 18 * k as i32), ("sans-serif", 13)))
                        .map_err(err)?;
                }
            }
        }
        Ok(())
    }
}

/// `text` in lines of at most `width` characters, broken after commas (a longer piece is
/// a line of its own).
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    for piece in text.split_inclusive(", ") {
        match lines.last_mut() {
            Some(l) if l.chars().count() + piece.trim_end().chars().count() <= width => {
                l.push_str(piece)
            }
            _ => lines.push(piece.to_string()),
        }
    }
    lines.iter().map(|l| l.trim_end().to_string()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Row names wrap after commas; a piece longer than the width is a line of its own.
    #[test]
    fn wrap_breaks_after_commas() {
        assert_eq!(wrap("ab, cd, ef", 6), ["ab,", "cd, ef"]);
        assert_eq!(wrap("abcdefgh, ij", 4), ["abcdefgh,", "ij"]);
        assert_eq!(wrap("short", 40), ["short"]);
    }
}
