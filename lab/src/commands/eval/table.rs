//! One Markdown table of the report: its header, how many leading columns are text (left
//! aligned; the rest are numbers, right aligned), and its rows of cells already formatted.

use std::fmt::Write as _;

pub(super) struct Table {
    head: Vec<String>,
    n_left: usize,
    rows: Vec<Vec<String>>,
}

impl Table {
    pub(super) fn new(head: &[&str], n_left: usize) -> Table {
        Table { head: head.iter().map(|h| h.to_string()).collect(), n_left, rows: Vec::new() }
    }

    pub(super) fn row(&mut self, cells: Vec<String>) {
        self.rows.push(cells);
    }

    /// Appends the table to `md`: `| a | b |`, the alignment row, then each row.
    pub(super) fn write(&self, md: &mut String) {
        let line = |md: &mut String, cells: &[String]| {
            let _ = writeln!(md, "| {} |", cells.join(" | "));
        };
        line(md, &self.head);
        let align: Vec<&str> =
            (0..self.head.len()).map(|k| if k < self.n_left { "---" } else { "---:" }).collect();
        let _ = writeln!(md, "|{}|", align.join("|"));
        for row in &self.rows {
            line(md, row);
        }
    }
}

/// `x` with `decimals` digits after the point.
pub(super) fn fixed(x: f64, decimals: usize) -> String {
    format!("{x:.decimals$}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_columns_are_left_and_numbers_right_aligned() {
        let mut table = Table::new(&["name", "n", "x"], 1);
        table.row(vec!["a".into(), "1".into(), fixed(0.5, 3)]);
        table.row(vec!["b".into(), String::new(), fixed(2.0, 1)]);
        let mut md = String::new();
        table.write(&mut md);
        assert_eq!(md, "| name | n | x |\n|---|---:|---:|\n| a | 1 | 0.500 |\n| b |  | 2.0 |\n");
    }
}
