//! Long sentences wrapped into lines, for the terminal and for comments in a file.

/// `text`'s words in lines of at most `columns` characters (a longer word alone on its
/// line), the first line starting with `first` and the others with `rest`, each word after a
/// space; every line ends with a newline.
pub fn wrap(text: &str, first: &str, rest: &str, columns: usize) -> String {
    let mut out = String::new();
    let mut line = String::from(first);
    let mut words = 0;
    for word in text.split_whitespace() {
        if words > 0 && line.chars().count() + 1 + word.chars().count() > columns {
            out.push_str(&line);
            out.push('\n');
            line = String::from(rest);
            words = 0;
        }
        line.push(' ');
        line.push_str(word);
        words += 1;
    }
    out.push_str(&line);
    out.push('\n');
    out
}
