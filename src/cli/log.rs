//! Log lines on stderr: on a terminal each one is wrapped at [`LOG_COLUMNS`] (continuation lines
//! indented under the message), so a long path or a long note never breaks in the middle of a
//! word at the terminal's edge; to a file or a pipe every event stays on one line, for grep.
use std::io::{IsTerminal, Write};

/// Widest log line on a terminal: the width of the progress line and the tables, with room.
pub const LOG_COLUMNS: usize = 100;

/// The writer of log events: stderr, wrapping each event on a terminal. An event that cannot be
/// written (a closed pipe) is dropped without a word, so that logging never ends the work.
pub struct Stderr {
    wrap: bool,
}

impl Default for Stderr {
    fn default() -> Stderr {
        Stderr { wrap: std::io::stderr().is_terminal() }
    }
}

impl<'a> tracing_subscriber::fmt::MakeWriter<'a> for Stderr {
    type Writer = EventWriter;

    fn make_writer(&'a self) -> EventWriter {
        EventWriter { wrap: self.wrap }
    }
}

/// Writes one formatted event (tracing-subscriber hands over each event whole).
pub struct EventWriter {
    wrap: bool,
}

impl Write for EventWriter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let mut err = std::io::stderr().lock();
        match std::str::from_utf8(buf) {
            Ok(text) if self.wrap => err.write_all(wrapped(text, LOG_COLUMNS).as_bytes())?,
            _ => err.write_all(buf)?,
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        std::io::stderr().flush()
    }
}

/// One piece of an event's text: a visible character or an escape sequence (zero columns).
fn pieces(text: &str) -> Vec<(&str, usize)> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(c) = rest.chars().next() {
        let len = if c == '\u{1b}' && rest[1..].starts_with('[') {
            // CSI: ESC [ parameters, then a final byte in @..~.
            rest[2..].find(|f: char| ('@'..='~').contains(&f)).map_or(rest.len(), |i| i + 3)
        } else {
            c.len_utf8()
        };
        let visible = usize::from(c != '\u{1b}');
        out.push((&rest[..len], visible));
        rest = &rest[len..];
    }
    out
}

/// `text` (events of `timestamp LEVEL message` lines, colour codes allowed) with every line
/// wider than `columns` broken at spaces, its continuation lines indented under the message. A
/// word wider than a line is left whole.
pub fn wrapped(text: &str, columns: usize) -> String {
    let mut out = String::with_capacity(text.len() + 64);
    for line in text.split_inclusive('\n') {
        let (line, newline) = match line.strip_suffix('\n') {
            Some(l) => (l, "\n"),
            None => (line, ""),
        };
        let p = pieces(line);
        if p.iter().map(|(_, w)| w).sum::<usize>() <= columns {
            out += line;
            out += newline;
            continue;
        }
        // The message starts after the second run of visible words (timestamp, level).
        let visible: String = p.iter().filter(|(_, w)| *w > 0).map(|(s, _)| *s).collect();
        let mut words = 0;
        let mut indent = 0;
        let mut in_word = false;
        for (i, ch) in visible.chars().enumerate() {
            if ch == ' ' {
                if in_word {
                    words += 1;
                }
                in_word = false;
                if words == 2 {
                    indent = i + 1;
                    break;
                }
            } else {
                in_word = true;
            }
        }
        if indent == 0 || indent >= columns / 2 {
            indent = 4;
        }
        let mut column = 0;
        let mut cut = p.len();
        for (i, (_, w)) in p.iter().enumerate() {
            if column == indent {
                cut = i;
                break;
            }
            column += w;
        }
        let head: String = p[..cut].iter().map(|(s, _)| *s).collect();
        let message: String = p[cut..].iter().map(|(s, _)| *s).collect();
        out += &head;
        let mut used = indent;
        let mut first = true;
        for word in message.split(' ') {
            let width = pieces(word).iter().map(|(_, w)| w).sum::<usize>();
            if !first && used + 1 + width > columns {
                out += "\n";
                out += &" ".repeat(indent);
                used = indent;
                first = true;
            }
            if !first {
                out += " ";
                used += 1;
            }
            out += word;
            used += width;
            first = false;
        }
        out += newline;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_events_wrap_under_their_message_and_keep_every_word() {
        let event = "2026-12-05T14:01:45.480528Z  INFO built the Embree BVH of /work/scenes/cornell-box/scene.gltf in 1.0 ms (36 triangles, fast traversal)\n";
        let out = wrapped(event, 100);
        let lines: Vec<&str> = out.lines().collect();
        assert_eq!(lines.len(), 2, "{out}");
        assert!(lines.iter().all(|l| l.chars().count() <= 100), "{out}");
        assert!(lines[1].starts_with(&" ".repeat(34)) && !lines[1][34..].starts_with(' '), "{out}");
        assert_eq!(out.split_whitespace().collect::<Vec<_>>(), event.split_whitespace().collect::<Vec<_>>());
        // Colour codes take no columns; a short event is left as it is.
        let coloured = "\u{1b}[2m2026-12-05T14:01:45.480528Z\u{1b}[0m \u{1b}[32m INFO\u{1b}[0m wrote x.exr\n";
        assert_eq!(wrapped(coloured, 100), coloured);
        let long = coloured.replace("wrote x.exr", &"word ".repeat(30));
        let out = wrapped(&long, 100);
        assert!(out.lines().all(|l| pieces(l).iter().map(|(_, w)| w).sum::<usize>() <= 100), "{out}");
        assert!(out.lines().nth(1).unwrap().starts_with(&" ".repeat(34)), "{out}");
    }
}
