//! A sample file for `glint tool tfit`: one number per line; `#` starts a comment (a whole line
//! or the end of one); blank lines are skipped.

/// At most this many samples (80 MB of f64).
pub const MAX_SAMPLES: usize = 10_000_000;

/// What is wrong with a sample file, with the line and column (1-based) where it is.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SamplesError {
    #[error(
        "{file}:{line}:{column}: `{text}` is not a number (one number per line, `#` comments)"
    )]
    NotANumber {
        file: String,
        line: usize,
        column: usize,
        text: String,
    },
    #[error("{file}:{line}:{column}: {value} is not finite")]
    NotFinite {
        file: String,
        line: usize,
        column: usize,
        value: f64,
    },
    #[error("{file}: more than {MAX_SAMPLES} samples")]
    TooMany { file: String },
}

/// The samples of `text`; `file` names it in errors.
pub fn parse(text: &str, file: &str) -> Result<Vec<f64>, SamplesError> {
    let mut out = vec![];
    for (i, raw) in text.lines().enumerate() {
        let body = raw.split('#').next().unwrap_or("");
        let token = body.trim();
        if token.is_empty() {
            continue;
        }
        let column = body.len() - body.trim_start().len() + 1;
        let value: f64 = token.parse().map_err(|_| SamplesError::NotANumber {
            file: file.into(),
            line: i + 1,
            column,
            text: token.chars().take(40).collect(),
        })?;
        if !value.is_finite() {
            return Err(SamplesError::NotFinite {
                file: file.into(),
                line: i + 1,
                column,
                value,
            });
        }
        if out.len() == MAX_SAMPLES {
            return Err(SamplesError::TooMany { file: file.into() });
        }
        out.push(value);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_comments_and_blank_lines() {
        let text = "# β_k [deg]\n1.5\n  -2e-3  # trailing\n\n\t7\n";
        assert_eq!(parse(text, "f").unwrap(), vec![1.5, -2e-3, 7.0]);
    }

    #[test]
    fn errors_name_line_and_column() {
        let e = parse("1\n  1.2.3\n", "s.txt").unwrap_err();
        assert_eq!(
            e.to_string(),
            "s.txt:2:3: `1.2.3` is not a number (one number per line, `#` comments)"
        );
        let e = parse("1 2\n", "s.txt").unwrap_err();
        assert!(
            matches!(
                e,
                SamplesError::NotANumber {
                    line: 1,
                    column: 1,
                    ..
                }
            ),
            "{e}"
        );
        let e = parse("0\nnan\n", "s.txt").unwrap_err();
        assert!(matches!(e, SamplesError::NotFinite { line: 2, .. }), "{e}");
    }
}
