//! Text fields of robokey's CSV files: always quoted (RFC 4180: inner quotes doubled), so
//! that a label holding a comma, a quote or a line break stays one field, and a spreadsheet
//! never reads a label as a number.

/// `text` as a quoted CSV field.
#[must_use]
pub fn quoted(text: &str) -> String {
    format!("\"{}\"", text.replace('"', "\"\""))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quoted_field_reads_back_as_one_field() {
        let text = "vs \"camera\" Eve, 8 mm\nsecond line";
        let line = format!("{},1\n", quoted(text));
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .from_reader(line.as_bytes());
        let record = reader.records().next().unwrap().unwrap();
        assert_eq!(record.len(), 2);
        assert_eq!(&record[0], text);
    }
}
