//! The message-type table is written once, in `MessageType`; docs/wire.md and the Wireshark
//! dissector (contrib/wireshark/robokey.lua) cannot share Rust code, so their copies are
//! checked against it here: every type's number and name, the reserved range, the layers the
//! page names, and which types the page says carry a step.

use std::collections::BTreeMap;
use std::path::Path;

use robokey::protocol::{Layer, MessageType};

fn read(relative: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(relative);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// `(byte, name)` of every type the Rust table holds.
fn rust_types() -> BTreeMap<u8, String> {
    MessageType::ALL
        .iter()
        .map(|t| (t.byte(), t.name().to_owned()))
        .collect()
}

fn layer_word(layer: Layer) -> &'static str {
    match layer {
        Layer::Handshake => "handshake",
        Layer::Session => "session",
        Layer::Closing => "closing",
        Layer::Post => "post",
    }
}

/// The cells of a Markdown table row, trimmed.
fn cells(line: &str) -> Vec<&str> {
    line.trim()
        .trim_matches('|')
        .split(" | ")
        .map(str::trim)
        .collect()
}

/// The rows of docs/wire.md's payload table: `| type | message | layer | …`.
fn doc_rows(page: &str) -> Vec<Vec<&str>> {
    let start = page
        .lines()
        .position(|l| l.starts_with("| type | message | layer |"))
        .expect("docs/wire.md has the payload table with a layer column");
    page.lines()
        .skip(start + 2)
        .take_while(|l| l.starts_with('|'))
        .map(cells)
        .collect()
}

#[test]
fn docs_wire_md_lists_every_type_with_its_number_name_and_layer() {
    let page = read("docs/wire.md");
    let mut named = BTreeMap::new();
    let mut reserved = None;
    for row in doc_rows(&page) {
        if row[1] == "reserved" {
            let (first, last) = row[0].split_once('–').expect("a range such as 17–21");
            reserved = Some(first.parse::<u8>().unwrap()..=last.parse::<u8>().unwrap());
            continue;
        }
        let byte: u8 = row[0]
            .parse()
            .unwrap_or_else(|_| panic!("type {:?}", row[0]));
        let name = row[1].trim_matches('`').to_owned();
        let kind = MessageType::from_byte(byte).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(row[2], layer_word(kind.layer()), "layer of {name}");
        named.insert(byte, name);
    }
    assert_eq!(named, rust_types());
    assert_eq!(reserved, Some(MessageType::RESERVED));
}

#[test]
fn docs_wire_md_names_the_types_that_carry_a_step() {
    let page = read("docs/wire.md");
    let row = page
        .lines()
        .find(|l| l.starts_with("| 12 | 4 | `step` |"))
        .expect("the header table's step row");
    // Every backticked name in the row's meaning, the field name itself aside.
    let named: Vec<&str> = cells(row)[3].split('`').skip(1).step_by(2).collect();
    let stepped: Vec<&str> = MessageType::ALL
        .iter()
        .filter(|t| t.carries_step())
        .map(|t| t.name())
        .collect();
    assert_eq!(named, stepped);
}

#[test]
fn the_wireshark_dissector_names_every_type_and_reserved_byte() {
    let script = read("contrib/wireshark/robokey.lua");
    let table = script
        .split_once("local types = {")
        .and_then(|(_, rest)| rest.split_once("\n}"))
        .expect("robokey.lua defines `local types = { … }`")
        .0;
    // Entries `[N] = "Name"`.
    let mut entries = BTreeMap::new();
    for entry in table.split('[').skip(1) {
        let (byte, rest) = entry.split_once(']').expect("[N]");
        let name = rest.split('"').nth(1).expect("a quoted name");
        let byte: u8 = byte.trim().parse().expect("a type number");
        assert!(
            entries.insert(byte, name.to_owned()).is_none(),
            "type {byte} twice"
        );
    }
    let mut expected = rust_types();
    for byte in MessageType::RESERVED {
        expected.insert(byte, format!("reserved: {}", MessageType::RESERVED_FOR));
    }
    assert_eq!(entries, expected);
}
