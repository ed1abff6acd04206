//! O-word control flow: subroutines (`sub`/`endsub`/`return`/`call`), loops
//! (`while`/`endwhile`, `do`/`while`, `repeat`/`endrepeat`, `break`, `continue`) and
//! conditionals (`if`/`elseif`/`else`/`endif`), with LinuxCNC's semantics: a false condition
//! skips forward to the next line with the same label, a loop end jumps back to the line that
//! opened it, labels are local to the subroutine they are written in.
//!
//! The main program is streamed ([`Lines`]); a subroutine's body is kept when its definition
//! is read (a call to a subroutine defined further down searches forward for it, as
//! LinuxCNC does). Every block executed counts against `GcodeOptions::max_blocks`.

use std::collections::HashMap;
use std::io::BufRead;
use std::rc::Rc;

use super::block::{read_block, scan_o_word, Block, Keyword, OWord};
use super::lexer::{compact_line, Significant};
use super::state::Interpreter;
use super::{program_error, LineError, Lines, SourceLine};
use crate::program::error::ProgramError;

/// Most nested subroutine calls (LinuxCNC `INTERP_SUB_ROUTINE_LEVELS` − 1).
const MAX_CALL_DEPTH: usize = 9;

/// A subroutine's body: the lines after `o<name> sub` up to its `o<name> endsub`.
#[derive(Debug)]
pub(super) struct Sub {
    pub lines: Vec<Rc<SourceLine>>,
    /// The line of the `sub` line (to recognise the definition when the main program reaches it).
    pub defined_at: usize,
}

/// Where a frame's lines come from.
#[derive(Debug, Clone)]
enum Code {
    Main,
    Sub(Rc<Sub>),
}

/// An open `if`, `do`, `while` or `repeat`: its keyword and the index of its line.
#[derive(Debug, Clone, Copy)]
struct Label {
    keyword: Keyword,
    index: usize,
    /// Passes left of a `repeat`; `None` until the loop starts.
    repeats_left: Option<i64>,
}

/// LinuxCNC's loop flags, which belong to the interpreter rather than to one loop.
#[derive(Debug, Default)]
pub(super) struct LoopFlags {
    pub doing_break: bool,
    pub doing_continue: bool,
}

/// One level of the call stack.
#[derive(Debug)]
pub(super) struct Frame {
    code: Code,
    name: String,
    /// Index of the next line in `code`.
    pc: usize,
    /// Skipping forward to the next line with this label.
    skip_to: Option<String>,
    labels: HashMap<String, Label>,
    /// Every label that opened an if or a loop in this frame, with its keyword and line:
    /// LinuxCNC refuses a label used again on another line.
    seen: HashMap<String, (Keyword, usize)>,
    executed_if: bool,
    /// Named parameters local to this call.
    pub locals: super::params::NameMap,
    /// The caller's #1–#30, restored on return.
    saved_arguments: [f64; 30],
}

impl Frame {
    pub fn main() -> Self {
        Frame {
            code: Code::Main,
            name: String::new(),
            pc: 0,
            skip_to: None,
            labels: HashMap::new(),
            seen: HashMap::new(),
            executed_if: false,
            locals: super::params::NameMap::default(),
            saved_arguments: [0.0; 30],
        }
    }

    /// The first main-program line a loop of this frame may jump back to.
    fn first_needed(&self) -> usize {
        self.labels
            .values()
            .filter(|label| label.keyword != Keyword::If)
            .map(|label| label.index)
            .min()
            .map_or(self.pc, |index| index.min(self.pc))
    }
}

/// Runs the program to its end, an M2/M30, the block limit or (inside O-word code) the first
/// error.
pub(super) fn run<R: BufRead>(interp: &mut Interpreter, lines: &mut Lines<R>) {
    let mut compact: Vec<Significant> = Vec::new();
    let mut block = Block::default();
    while !interp.finished {
        let frame = interp.frames.last_mut().expect("main frame");
        let index = frame.pc;
        let line = match &frame.code {
            Code::Main => lines.get(index),
            Code::Sub(sub) => sub.lines.get(index).cloned(),
        };
        let Some(line) = line else {
            end_of_code(interp);
            break;
        };
        interp.frames.last_mut().expect("frame").pc += 1;
        interp.blocks += 1;
        if interp.blocks > interp.options.gcode.max_blocks {
            let limit = interp.options.gcode.max_blocks;
            report(
                interp,
                &line,
                LineError::new(0, line.text.len(), format!(
                    "expected the program to end within {limit} executed blocks; it runs on (an endless loop?)"
                ))
                .hint("check the loop conditions; the limit is GcodeOptions::max_blocks"),
            );
            interp.finished = true;
            break;
        }
        let outcome = one_line(interp, lines, &line, index, &mut compact, &mut block);
        if !interp.seen_nonblank && line.text.iter().any(|b| !b.is_ascii_whitespace()) {
            interp.seen_nonblank = true;
        }
        if let Err(error) = outcome {
            report(interp, &line, error);
            if in_control_flow(interp) {
                interp.finished = true;
            }
        }
        if interp.frames.len() == 1 {
            let keep_from = interp.frames[0].first_needed();
            lines.release_before(keep_from);
        } else {
            lines.release_before(interp.frames[0].first_needed());
        }
    }
}

fn report(interp: &mut Interpreter, line: &SourceLine, error: LineError) {
    // An error found without a position points at the whole block.
    let (start, end) = super::block_text_range(&line.text);
    let error = error.located(start, end);
    let error = program_error(interp.source, line, error);
    interp.errors.push(error);
}

fn in_control_flow(interp: &Interpreter) -> bool {
    interp.frames.len() > 1
        || interp
            .frames
            .iter()
            .any(|frame| frame.skip_to.is_some() || !frame.labels.is_empty())
}

/// The main program ran out of lines (a subroutine's body always ends in its endsub).
fn end_of_code(interp: &mut Interpreter) {
    let frame = &interp.frames[0];
    if let Some(label) = &frame.skip_to {
        let problem = format!(
            "expected a line with label o{} before the end of the file (an if, loop or subroutine is not closed)",
            shown(label)
        );
        let error = ProgramError::new(interp.source, None, problem);
        interp.errors.push(error);
    }
}

fn shown(label: &str) -> String {
    if label.bytes().all(|b| b.is_ascii_digit()) {
        label.to_string()
    } else {
        format!("<{label}>")
    }
}

fn one_line<R: BufRead>(
    interp: &mut Interpreter,
    lines: &mut Lines<R>,
    line: &Rc<SourceLine>,
    index: usize,
    compact: &mut Vec<Significant>,
    block: &mut Block,
) -> Result<(), LineError> {
    compact.clear();
    let message = compact_line(&line.text, compact)?;
    let skipping = interp.frames.last().expect("frame").skip_to.clone();
    if let Some(target) = &skipping {
        // Skipped code is not read, only searched for the label.
        match scan_o_word(&line.text, compact) {
            Some((label, _)) if &label == target => {}
            _ => return Ok(()),
        }
    }
    if let super::lexer::ActiveComment::Abort { start, end } = message {
        let text = String::from_utf8_lossy(&line.text[start..end])
            .trim()
            .to_string();
        interp.finished = true;
        return Err(LineError::new(
            start,
            end,
            format!("expected no (ABORT,…) comment: the program aborts here ({text})"),
        ));
    }
    let Some(first) = compact.first().copied() else {
        return Ok(());
    };
    interp.line_number = line.number;
    if first.byte == b'%' {
        return percent_line(interp, line, compact);
    }
    interp.seen_content = true;
    let mut words: &[Significant] = compact;
    if first.byte == b'/' {
        if interp.s.block_delete {
            return Ok(());
        }
        words = &words[1..];
    }
    read_block(&line.text, words, interp, block)?;
    if let Some(o_word) = &block.o_word {
        for (target, value) in &block.settings {
            interp.set_parameter(target, *value);
        }
        return o_line(interp, lines, line, index, o_word, skipping.is_some());
    }
    for (target, value) in &block.settings {
        interp.set_parameter(target, *value);
    }
    if let super::lexer::ActiveComment::Message { start, end } = message {
        let text = String::from_utf8_lossy(&line.text[start..end])
            .trim()
            .to_string();
        let span = super::span_in_line(line, first.at);
        interp
            .canon
            .program
            .warnings
            .push(crate::program::types::Warning {
                span,
                message: format!("message: {text}"),
            });
    }
    if !block.has_codes {
        return Ok(());
    }
    let span = super::span_in_line(line, first.at);
    interp.execute(&line.text, block, span)
}

fn percent_line(
    interp: &mut Interpreter,
    line: &SourceLine,
    compact: &[Significant],
) -> Result<(), LineError> {
    let first = compact[0];
    if compact.len() > 1 {
        return Err(LineError::new(
            first.at,
            line.text.len(),
            "expected nothing after '%' on its line",
        ));
    }
    if !interp.seen_nonblank {
        interp.percent_open = true;
    } else if interp.percent_open {
        // LinuxCNC stops reading at the closing '%'.
        interp.finished = true;
    } else {
        return Err(LineError::new(
            first.at,
            first.at + 1,
            "expected '%' only on the first line, or to close a program that opened with '%'",
        ));
    }
    interp.seen_content = true;
    Ok(())
}

/// Executes an O-word line.
fn o_line<R: BufRead>(
    interp: &mut Interpreter,
    lines: &mut Lines<R>,
    line: &Rc<SourceLine>,
    index: usize,
    o: &OWord,
    was_skipping: bool,
) -> Result<(), LineError> {
    let error = |problem: String| LineError::new(o.start, o.end, problem);
    let depth = interp.frames.len() - 1;
    let frame = interp.frames.last_mut().expect("frame");
    let condition = o.values.first().copied().unwrap_or(0.0);
    if matches!(
        o.keyword,
        Keyword::If | Keyword::Do | Keyword::While | Keyword::Repeat
    ) {
        let closes_do = o.keyword == Keyword::While
            && frame
                .seen
                .get(&o.label)
                .is_some_and(|(keyword, _)| *keyword == Keyword::Do);
        match frame.seen.get(&o.label) {
            Some(&(_, first_line)) if first_line != line.number && !closes_do => {
                return Err(error(format!(
                    "expected each if/loop label once; o{} was already used on line {first_line}",
                    shown(&o.label)
                ))
                .hint(
                    "LinuxCNC refuses a label used again; give each if and loop its own number",
                ));
            }
            Some(_) => {}
            None => {
                frame.seen.insert(o.label.clone(), (o.keyword, line.number));
            }
        }
    }
    match o.keyword {
        Keyword::Sub => {
            if depth > 0 {
                return Err(error(format!(
                    "expected no subroutine definition inside subroutine o{}",
                    shown(&frame.name)
                )));
            }
            if let Some(existing) = interp.subs.get(&o.label) {
                return Err(if existing.defined_at == line.number {
                    error(format!(
                        "expected subroutine o{} to be defined before it is called: LinuxCNC refuses to run into a definition it found by searching forward",
                        shown(&o.label)
                    ))
                    .hint("define subroutines before the main program, or after its M2/M30")
                } else {
                    error(format!(
                        "expected one definition of subroutine o{}; it was already defined on line {}",
                        shown(&o.label),
                        existing.defined_at
                    ))
                });
            }
            let (sub, end_index) = collect_sub(lines, index, &o.label, line.number)?;
            interp.subs.insert(o.label.clone(), Rc::new(sub));
            interp.frames.last_mut().expect("frame").pc = end_index + 1;
        }
        Keyword::EndSub | Keyword::Return => {
            if depth == 0 {
                return Err(error(format!(
                    "expected '{}' only inside a subroutine; o{} is not being defined or called",
                    o.keyword.name(),
                    shown(&o.label)
                )));
            }
            // LinuxCNC returns whatever label the return carries.
            interp.returned = match o.values.first() {
                Some(&value) => (value, true),
                None => (0.0, false),
            };
            let frame = interp.frames.pop().expect("sub frame");
            interp.params.set_arguments(&frame.saved_arguments);
        }
        Keyword::Call => {
            let Some(sub) = find_sub(interp, lines, &o.label)? else {
                return Err(error(format!(
                    "expected a definition of subroutine o{} (o{} sub … o{} endsub) in this file",
                    shown(&o.label),
                    shown(&o.label),
                    shown(&o.label)
                ))
                .hint("cncsim reads one file; LinuxCNC would also look for a file of that name in its subroutine path"));
            };
            if depth >= MAX_CALL_DEPTH {
                return Err(error(format!(
                    "expected at most {MAX_CALL_DEPTH} nested subroutine calls"
                )));
            }
            let mut arguments = [0.0; 30];
            arguments[..o.values.len()].copy_from_slice(&o.values);
            let saved = interp.params.arguments();
            interp.params.set_arguments(&arguments);
            interp.returned = (0.0, false);
            interp.frames.push(Frame {
                code: Code::Sub(sub),
                name: o.label.clone(),
                saved_arguments: saved,
                ..Frame::main()
            });
        }
        Keyword::Do => {
            frame.skip_to = None;
            frame.labels.entry(o.label.clone()).or_insert(Label {
                keyword: Keyword::Do,
                index,
                repeats_left: None,
            });
        }
        Keyword::While => {
            let existing = frame.labels.get(&o.label).copied();
            match existing {
                Some(label) if label.keyword == Keyword::Do => {
                    // The end of a do-while loop.
                    // LinuxCNC keeps the break flag across loops until a do-while
                    // ends: a `break` out of an earlier while also ends the next do-while
                    // after one pass. cncsim does the same.
                    frame.skip_to = None;
                    if condition != 0.0 && !interp.flow.doing_break {
                        frame.pc = label.index;
                    } else {
                        frame.labels.remove(&o.label);
                    }
                    interp.flow.doing_break = false;
                }
                _ => {
                    frame.skip_to = None;
                    frame.labels.insert(
                        o.label.clone(),
                        Label {
                            keyword: Keyword::While,
                            index,
                            repeats_left: None,
                        },
                    );
                    if condition == 0.0 {
                        frame.skip_to = Some(o.label.clone());
                    }
                }
            }
        }
        Keyword::Repeat => {
            frame.skip_to = None;
            let label = frame.labels.entry(o.label.clone()).or_insert(Label {
                keyword: Keyword::Repeat,
                index,
                repeats_left: None,
            });
            let left = label.repeats_left.unwrap_or(condition.round() as i64);
            if left > 0 {
                label.repeats_left = Some(left - 1);
            } else {
                label.repeats_left = None;
                frame.skip_to = Some(o.label.clone());
            }
        }
        Keyword::EndWhile | Keyword::EndRepeat => {
            let opener = if o.keyword == Keyword::EndWhile {
                Keyword::While
            } else {
                Keyword::Repeat
            };
            let Some(label) = frame
                .labels
                .get(&o.label)
                .copied()
                .filter(|l| l.keyword == opener)
            else {
                return Err(error(format!(
                    "expected an open 'o{} {}' before this '{}'",
                    shown(&o.label),
                    opener.name(),
                    o.keyword.name()
                )));
            };
            if was_skipping {
                frame.skip_to = None;
                if interp.flow.doing_continue {
                    interp.flow.doing_continue = false;
                    frame.pc = label.index;
                } else {
                    frame.labels.remove(&o.label);
                }
            } else {
                frame.pc = label.index;
            }
        }
        Keyword::If => {
            frame.labels.insert(
                o.label.clone(),
                Label {
                    keyword: Keyword::If,
                    index,
                    repeats_left: None,
                },
            );
            if condition != 0.0 {
                frame.skip_to = None;
                frame.executed_if = true;
            } else {
                frame.skip_to = Some(o.label.clone());
                frame.executed_if = false;
            }
        }
        Keyword::ElseIf | Keyword::Else | Keyword::EndIf => {
            if frame.labels.get(&o.label).map(|l| l.keyword) != Some(Keyword::If) {
                return Err(error(format!(
                    "expected an open 'o{} if' before this '{}'",
                    shown(&o.label),
                    o.keyword.name()
                )));
            }
            match o.keyword {
                Keyword::EndIf => {
                    frame.skip_to = None;
                    frame.executed_if = true;
                    frame.labels.remove(&o.label);
                }
                _ if frame.executed_if => frame.skip_to = Some(o.label.clone()),
                Keyword::Else => {
                    frame.skip_to = None;
                    frame.executed_if = true;
                }
                _ if condition != 0.0 => {
                    frame.skip_to = None;
                    frame.executed_if = true;
                }
                _ => frame.skip_to = Some(o.label.clone()),
            }
        }
        Keyword::Break | Keyword::Continue => {
            if !matches!(
                frame.labels.get(&o.label).map(|l| l.keyword),
                Some(Keyword::While | Keyword::Do)
            ) {
                return Err(error(format!(
                    "expected an open 'o{} while' or 'o{} do' loop for this '{}'",
                    shown(&o.label),
                    shown(&o.label),
                    o.keyword.name()
                )));
            }
            if o.keyword == Keyword::Continue && was_skipping {
                // Reached while already skipping to this loop's end: nothing to do.
                return Ok(());
            }
            frame.skip_to = Some(o.label.clone());
            if o.keyword == Keyword::Break {
                interp.flow.doing_break = true;
            } else {
                interp.flow.doing_continue = true;
            }
        }
    }
    Ok(())
}

/// The body of the subroutine whose `sub` line is main line `index`: every line up to its
/// `endsub`. Returns it and the index of the `endsub` line.
fn collect_sub<R: BufRead>(
    lines: &mut Lines<R>,
    index: usize,
    name: &str,
    line_number: usize,
) -> Result<(Sub, usize), LineError> {
    let mut body = Vec::new();
    let mut compact = Vec::new();
    let mut next = index + 1;
    loop {
        let Some(line) = lines.get(next) else {
            return Err(LineError::new(
                0,
                0,
                format!(
                    "expected 'o{} endsub' to end the subroutine defined here",
                    shown(name)
                ),
            )
            .found(crate::program::error::Found::EndOfFile));
        };
        compact.clear();
        let o_word = compact_line(&line.text, &mut compact)
            .ok()
            .and_then(|_| scan_o_word(&line.text, &compact));
        body.push(line.clone());
        match o_word {
            Some((label, Keyword::EndSub)) if label == name => break,
            Some((label, Keyword::Sub)) => {
                return Err(LineError::new(0, 0, format!(
                    "expected 'o{} endsub' before another subroutine definition (line {}); definitions do not nest",
                    shown(name),
                    line.number
                ))
                .found(crate::program::error::Found::Text(format!("o{} sub", shown(&label)))));
            }
            _ => {}
        }
        next += 1;
    }
    Ok((
        Sub {
            lines: body,
            defined_at: line_number,
        },
        next,
    ))
}

/// A subroutine by name, searching forward through the main program for its definition if
/// it has not been read yet (LinuxCNC does the same).
fn find_sub<R: BufRead>(
    interp: &mut Interpreter,
    lines: &mut Lines<R>,
    name: &str,
) -> Result<Option<Rc<Sub>>, LineError> {
    if let Some(sub) = interp.subs.get(name) {
        return Ok(Some(sub.clone()));
    }
    let mut compact = Vec::new();
    let mut next = interp.frames[0].pc;
    while let Some(line) = lines.get(next) {
        compact.clear();
        let o_word = compact_line(&line.text, &mut compact)
            .ok()
            .and_then(|_| scan_o_word(&line.text, &compact));
        if let Some((label, Keyword::Sub)) = o_word {
            if label == name {
                let (sub, _) = collect_sub(lines, next, name, line.number)?;
                let sub = Rc::new(sub);
                interp.subs.insert(name.to_string(), sub.clone());
                return Ok(Some(sub));
            }
        }
        next += 1;
    }
    Ok(None)
}
