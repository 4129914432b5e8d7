//! A problem in a text file the user wrote (a site file, an MSU
//! configuration), located by line and column, and the message that lists
//! every problem of one file.

use std::ops::Range;

/// One problem found in a file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FileIssue {
    /// 1-based line of the offending value (0 when the problem concerns the whole file).
    pub line: usize,
    /// 1-based column of the offending value.
    pub column: usize,
    /// Dotted path of the field, e.g. `transmitters[3].position`.
    pub field: String,
    /// What is wrong, in plain words.
    pub message: String,
}

impl FileIssue {
    /// The problem `message` with `field`, at the start of byte range `span` of `text`.
    pub fn at(
        text: &str,
        span: Range<usize>,
        field: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        let offset = span.start.min(text.len());
        let before = &text[..offset];
        Self {
            line: before.matches('\n').count() + 1,
            column: before.rfind('\n').map_or(offset, |nl| offset - nl - 1) + 1,
            field: field.into(),
            message: message.into(),
        }
    }
}

impl std::fmt::Display for FileIssue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}:{}: {}: {}",
            self.line, self.column, self.field, self.message
        )
    }
}

/// `"{what} {file} has N problems:"`, then one line per issue naming file,
/// line, column and field.
pub fn render_issues(what: &str, file: &str, issues: &[FileIssue]) -> String {
    let mut out = format!(
        "{what} {file} has {} problem{}:",
        issues.len(),
        if issues.len() == 1 { "" } else { "s" }
    );
    for i in issues {
        out.push_str(&format!("\n  {file}:{i}"));
    }
    out
}
