//! Where in a scene file a bad `constraints:` entry is. serde reads the tagged constraint kinds
//! through a buffer, so its errors lose the entry's index, the field and the line ("at line 4",
//! the list's first line, for an error ten lines below); this finds them again.

use crate::constraints::ConstraintSpec;

/// For a scene `text` that failed to parse: the failing constraint's index, name, field and
/// line, with the reason (`None` when the error is not inside `constraints:` or the list is
/// not written as a block sequence).
pub(crate) fn locate_constraint_error(text: &str) -> Option<String> {
    let doc: serde_yaml::Value = serde_yaml::from_str(text).ok()?;
    let items = doc.get("constraints")?.as_sequence()?;
    let (index, reason) = items.iter().enumerate().find_map(|(i, item)| {
        serde_yaml::from_value::<ConstraintSpec>(item.clone())
            .err()
            .map(|e| (i, e.to_string()))
    })?;
    let name = items[index]
        .get("name")
        .and_then(|n| n.as_str())
        .map(|n| format!(" '{n}'"))
        .unwrap_or_default();
    let lines: Vec<&str> = text.lines().collect();
    let (start, end) = item_lines(&lines, index)?;
    // The line of the field the reason names (`unknown field `radus``), or of the value it
    // quotes (`invalid type: string "abc"`); else the entry's first line.
    let quoted = |open: char, close: char| {
        let a = reason.find(open)? + open.len_utf8();
        let b = a + reason[a..].find(close)?;
        Some(reason[a..b].to_string())
    };
    let field = quoted('`', '`').filter(|_| reason.starts_with("unknown field"));
    let value = quoted('"', '"');
    // `key: value` on one line, block or flow style: the key is the word before the colon.
    let key_of_value = |s: &str, v: &str| -> Option<String> {
        let pos = s
            .find(&format!(": {v}"))
            .or_else(|| s.find(&format!(":{v}")))?;
        let key = s[..pos]
            .rsplit(|c: char| !(c.is_alphanumeric() || c == '_'))
            .next()?;
        (!key.is_empty()).then(|| key.to_string())
    };
    let (at, key) = (start..end)
        .find_map(|l| match (&field, &value) {
            (Some(f), _) if lines[l].contains(&format!("{f}:")) => Some((l, Some(f.clone()))),
            (None, Some(v)) => key_of_value(lines[l], v).map(|k| (l, Some(k))),
            _ => None,
        })
        .unwrap_or((start, None));
    let key = key.map(|k| format!(", field `{k}`")).unwrap_or_default();
    Some(format!(
        "constraints[{index}]{name}{key} (line {}): {reason}",
        at + 1
    ))
}

/// Lines [start, end) of block-sequence entry `index` under the top-level `constraints:` key.
fn item_lines(lines: &[&str], index: usize) -> Option<(usize, usize)> {
    let head = lines
        .iter()
        .position(|l| l.starts_with("constraints:") && l.trim_end() == "constraints:")?;
    let body_end = (head + 1..lines.len())
        .find(|&l| {
            let s = lines[l];
            !s.trim().is_empty()
                && !s.starts_with(' ')
                && !s.starts_with('-')
                && !s.starts_with('#')
        })
        .unwrap_or(lines.len());
    let starts: Vec<usize> = (head + 1..body_end)
        .filter(|&l| lines[l].trim_start().starts_with('-'))
        .collect();
    let indent = starts
        .iter()
        .map(|&l| lines[l].len() - lines[l].trim_start().len())
        .min()?;
    let starts: Vec<usize> = starts
        .into_iter()
        .filter(|&l| lines[l].len() - lines[l].trim_start().len() == indent)
        .collect();
    let start = *starts.get(index)?;
    Some((start, starts.get(index + 1).copied().unwrap_or(body_end)))
}
