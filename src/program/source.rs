//! Source positions: turning byte offsets into 1-based lines and columns.

use super::types::Span;

/// 1-based column of byte `byte_in_line` within `line`, counting characters (UTF-8 sequences)
/// rather than bytes so that columns match what an editor shows.
pub(super) fn char_column(line: &[u8], byte_in_line: usize) -> u32 {
    let end = byte_in_line.min(line.len());
    let chars = line[..end].iter().filter(|&&b| (b & 0xC0) != 0x80).count();
    saturate(chars + 1)
}

pub(super) fn saturate(value: usize) -> u32 {
    u32::try_from(value).unwrap_or(u32::MAX)
}

/// Start offsets of the lines of a whole text, for files parsed in one piece (HPGL, APT).
pub(super) struct LineIndex<'t> {
    text: &'t [u8],
    starts: Vec<usize>,
    /// The last position looked up: (offset, its line start, its column). Readers move
    /// forwards, so counting characters from here keeps long one-line files (HPGL) linear.
    last: std::cell::Cell<(usize, usize, u32)>,
}

impl<'t> LineIndex<'t> {
    pub(super) fn new(text: &'t [u8]) -> Self {
        let mut starts = vec![0];
        starts.extend(
            text.iter()
                .enumerate()
                .filter(|(_, &b)| b == b'\n')
                .map(|(index, _)| index + 1),
        );
        LineIndex {
            text,
            starts,
            last: std::cell::Cell::new((0, 0, 1)),
        }
    }

    /// The span of byte `offset` (clamped to the end of the text).
    pub(super) fn span(&self, offset: usize) -> Span {
        let offset = offset.min(self.text.len());
        // Index of the last line start <= offset.
        let line_index = self.starts.partition_point(|&start| start <= offset) - 1;
        let line_start = self.starts[line_index];
        let (last_offset, last_line_start, last_column) = self.last.get();
        let column = if last_line_start == line_start && last_offset <= offset {
            let more = char_column(&self.text[last_offset..], offset - last_offset) - 1;
            last_column.saturating_add(more)
        } else {
            char_column(&self.text[line_start..], offset - line_start)
        };
        self.last.set((offset, line_start, column));
        Span {
            line: saturate(line_index + 1),
            column,
            byte_offset: saturate(offset),
        }
    }
}
