//! Tables as Parquet files (`--format parquet`): the columns of a [`crate::table::Column`] list
//! with their Arrow types (float64, uint64, int64, bool, string; undefined values null), each
//! field's unit and meaning in its metadata (`unit`, `description`), Snappy-compressed pages in
//! one row group. The same table always gives the same bytes.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow_array::cast::AsArray;
use arrow_array::types::{Float64Type, Int64Type, UInt64Type};
use arrow_array::{
    Array, ArrayRef, BooleanArray, Float64Array, Int64Array, RecordBatch, StringArray, UInt64Array,
};
use arrow_schema::{DataType, Field, Schema};
use parquet::arrow::ArrowWriter;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::basic::Compression;
use parquet::file::properties::WriterProperties;

use crate::error::LabError;
use crate::table::{Column, Values};

/// The format a command writes its tables in (`--format`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TableFormat {
    /// Comma-separated text (`runs.csv`, `trace.csv`, `secrecy.csv`).
    #[default]
    Csv,
    /// Apache Parquet (`runs.parquet`, `trace.parquet`, `secrecy.parquet`).
    Parquet,
}

impl TableFormat {
    /// The file extension of its tables.
    #[must_use]
    pub fn extension(self) -> &'static str {
        match self {
            Self::Csv => "csv",
            Self::Parquet => "parquet",
        }
    }
}

/// A Parquet error on `path`.
fn malformed(path: &Path, error: impl std::fmt::Display) -> LabError {
    LabError::Malformed {
        place: path.display().to_string(),
        message: error.to_string(),
    }
}

/// A column's values as an Arrow array.
fn array(values: &Values) -> ArrayRef {
    match values {
        Values::Reals(v) => Arc::new(Float64Array::from(v.clone())),
        Values::Counts(v) => Arc::new(UInt64Array::from(v.clone())),
        Values::Integers(v) => Arc::new(Int64Array::from(v.clone())),
        Values::Flags(v) => Arc::new(BooleanArray::from(v.clone())),
        Values::Texts(v) => Arc::new(StringArray::from_iter_values(v)),
    }
}

/// Writes `columns` (of equal length) to the Parquet file `path`, with `metadata` as the
/// schema's key-value metadata (e.g. the resolved sweep definition).
///
/// # Errors
/// Columns of different lengths, or the file cannot be written.
pub fn write_parquet(
    path: &Path,
    columns: &[Column],
    metadata: &[(&str, String)],
) -> Result<PathBuf, LabError> {
    let fields: Vec<Field> = columns
        .iter()
        .map(|c| {
            let mut meta = BTreeMap::from([("unit".to_owned(), c.unit.clone())]);
            if !c.description.is_empty() {
                meta.insert("description".to_owned(), c.description.clone());
            }
            let array = array(&c.values);
            Field::new(&c.name, array.data_type().clone(), true).with_metadata(meta)
        })
        .collect();
    let metadata: BTreeMap<String, String> = metadata
        .iter()
        .map(|(k, v)| ((*k).to_owned(), v.clone()))
        .collect();
    let schema = Arc::new(Schema::new_with_metadata(fields, metadata));
    let batch = RecordBatch::try_new(
        schema.clone(),
        columns.iter().map(|c| array(&c.values)).collect(),
    )
    .map_err(|e| malformed(path, e))?;
    let properties = WriterProperties::builder()
        .set_compression(Compression::SNAPPY)
        .build();
    let file = std::fs::File::create(path).map_err(crate::error::io_at(path))?;
    let mut writer =
        ArrowWriter::try_new(file, schema, Some(properties)).map_err(|e| malformed(path, e))?;
    writer.write(&batch).map_err(|e| malformed(path, e))?;
    writer.close().map_err(|e| malformed(path, e))?;
    Ok(path.to_path_buf())
}

/// A table read back from Parquet: its columns and its schema's metadata.
#[derive(Clone, Debug, PartialEq)]
pub struct ParquetTable {
    /// The columns, in the file's order.
    pub columns: Vec<Column>,
    /// The schema's key-value metadata.
    pub metadata: BTreeMap<String, String>,
}

/// Appends `array`'s values to `values` (of the same type).
fn extend(values: &mut Values, array: &dyn Array) -> Option<()> {
    match values {
        Values::Reals(v) => v.extend(array.as_primitive_opt::<Float64Type>()?.iter()),
        Values::Counts(v) => v.extend(array.as_primitive_opt::<UInt64Type>()?.iter()),
        Values::Integers(v) => {
            let array = array.as_primitive_opt::<Int64Type>()?;
            if array.null_count() > 0 {
                return None;
            }
            v.extend(array.values().iter());
        }
        Values::Flags(v) => v.extend(array.as_boolean_opt()?.iter()),
        Values::Texts(v) => {
            let array = array.as_string_opt::<i32>()?;
            if array.null_count() > 0 {
                return None;
            }
            v.extend(array.iter().map(|s| s.unwrap_or_default().to_owned()));
        }
    }
    Some(())
}

/// Reads a Parquet file that [`write_parquet`] wrote.
///
/// # Errors
/// The file cannot be read, is not Parquet, or holds a column of a type robokey does not
/// write (or nulls where robokey writes none).
pub fn read_parquet(path: &Path) -> Result<ParquetTable, LabError> {
    let file = std::fs::File::open(path).map_err(crate::error::io_at(path))?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).map_err(|e| malformed(path, e))?;
    let schema = builder.schema().clone();
    let mut columns = schema
        .fields()
        .iter()
        .map(|field| {
            let values = match field.data_type() {
                DataType::Float64 => Values::Reals(Vec::new()),
                DataType::UInt64 => Values::Counts(Vec::new()),
                DataType::Int64 => Values::Integers(Vec::new()),
                DataType::Boolean => Values::Flags(Vec::new()),
                DataType::Utf8 => Values::Texts(Vec::new()),
                other => {
                    return Err(malformed(
                        path,
                        format!(
                            "column `{}` is {other}, not a type robokey writes",
                            field.name()
                        ),
                    ));
                }
            };
            let meta = |key: &str| field.metadata().get(key).cloned().unwrap_or_default();
            Ok(Column {
                name: field.name().clone(),
                unit: meta("unit"),
                description: meta("description"),
                values,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    for batch in builder.build().map_err(|e| malformed(path, e))? {
        let batch = batch.map_err(|e| malformed(path, e))?;
        for (column, array) in columns.iter_mut().zip(batch.columns()) {
            extend(&mut column.values, array.as_ref()).ok_or_else(|| {
                malformed(
                    path,
                    format!(
                        "column `{}` holds nulls where robokey writes none",
                        column.name
                    ),
                )
            })?;
        }
    }
    Ok(ParquetTable {
        columns,
        metadata: schema.metadata().clone().into_iter().collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_table_reads_back_with_its_units_and_metadata() {
        let dir = std::env::temp_dir().join(format!("robokey-parquet-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.parquet");
        let columns = vec![
            Column::new(
                "x",
                "m",
                "a length",
                Values::Reals(vec![Some(0.1), None, Some(-2.5)]),
            ),
            Column::new(
                "n",
                "",
                "",
                Values::Counts(vec![Some(1), Some(u64::MAX), None]),
            ),
            Column::new("i", "", "", Values::Integers(vec![-1, 0, 7])),
            Column::new(
                "f",
                "",
                "",
                Values::Flags(vec![None, Some(true), Some(false)]),
            ),
            Column::new(
                "s",
                "",
                "",
                Values::Texts(vec!["a, \"b\"".into(), String::new(), "ℓ".into()]),
            ),
        ];
        write_parquet(&path, &columns, &[("robokey.test", "yes".into())]).unwrap();
        let first = std::fs::read(&path).unwrap();
        let table = read_parquet(&path).unwrap();
        assert_eq!(table.columns, columns);
        assert_eq!(
            table.metadata.get("robokey.test").map(String::as_str),
            Some("yes")
        );
        write_parquet(&path, &columns, &[("robokey.test", "yes".into())]).unwrap();
        assert_eq!(
            std::fs::read(&path).unwrap(),
            first,
            "the same table, the same bytes"
        );
        std::fs::write(&path, b"not parquet").unwrap();
        let err = read_parquet(&path).unwrap_err().to_string();
        assert!(err.starts_with(&format!("{}: ", path.display())), "{err}");
        let short = vec![
            columns[0].clone(),
            Column::new("y", "", "", Values::Integers(vec![1])),
        ];
        assert!(write_parquet(&path, &short, &[]).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
