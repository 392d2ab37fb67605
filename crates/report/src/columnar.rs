//! `trace.parquet`: the trace as a Parquet file, for pandas (`pd.read_parquet`, with pyarrow),
//! polars, DuckDB, Arrow and Spark without parsing text.
//!
//! The columns are those of `trace.csv` with the same names and units, one row per cycle
//! and axis in the same order, but every value is the exact `f64` the run recorded (the CSV
//! rounds to 6 or 9 decimals) and a command that never arrived is NaN in `apply_time_s`
//! (empty in the CSV). `axis` is a 32-bit integer, every other column a double. Snappy
//! compression, row groups of at most [`ROW_GROUP_ROWS`] rows (each built from the run's
//! columns as it is written: the file is never held whole in memory), the column units and
//! the scenario's name in the file's key-value metadata. A part program's run (docs/programs.md)
//! adds three columns: `x_mm` and `x_d_mm` (the axis's true and desired position through its
//! transmission) and `contour_error_mm` (the cycle's, on each of its rows), and
//! `ringsync.machine` in the metadata says which machine axis each ring axis drives.
//!
//! Why Parquet rather than Arrow IPC: pandas, polars, DuckDB and Spark all read it, where
//! pandas reads Arrow IPC only through pyarrow's own calls; and the `parquet` crate without
//! its Arrow layer builds in about 27 s cold here (Arrow's array crates would add theirs).

use std::io::Write;
use std::sync::Arc;

use ::parquet::basic::Compression;
use ::parquet::data_type::{DoubleType, Int32Type};
use ::parquet::errors::ParquetError;
use ::parquet::file::metadata::KeyValue;
use ::parquet::file::properties::WriterProperties;
use ::parquet::file::writer::SerializedFileWriter;
use ::parquet::schema::parser::parse_message_type;

use ringsync_model::result::{RunResult, Trace};

/// Most rows in one row group (a group's columns are built in memory: about 40 MB at most).
pub const ROW_GROUP_ROWS: usize = 1 << 19;

/// The Parquet schema of the trace: the columns of `trace.csv`, in its order.
const SCHEMA: &str = "message ringsync_trace {
  REQUIRED DOUBLE t_s;
  REQUIRED INT32 axis;
  REQUIRED DOUBLE x_d_rad;
  REQUIRED DOUBLE x_rad;
  REQUIRED DOUBLE e_rad;
  REQUIRED DOUBLE eps_rad;
  REQUIRED DOUBLE u_v;
  REQUIRED DOUBLE sample_time_s;
  REQUIRED DOUBLE apply_time_s;
  REQUIRED DOUBLE clock_error_ns;
}";

/// What each column holds, for the file's metadata (`ringsync.columns`).
const COLUMNS: &str = "t_s: cycle start [s]; axis: 1-based; x_d_rad: desired position at the \
cycle start [rad]; x_rad: true position at the cycle start [rad]; e_rad: x_d - x [rad]; \
eps_rad: synchronisation error [rad]; u_v: command computed in the cycle [V]; sample_time_s: \
sampling instant of the sample the command used [s]; apply_time_s: when the command took \
effect at the slave [s], NaN if it never arrived; clock_error_ns: slave clock minus true time \
at the cycle start [ns]";

/// The columns a part program's run adds (docs/programs.md).
const PATH_SCHEMA: &str = "
  REQUIRED DOUBLE x_mm;
  REQUIRED DOUBLE x_d_mm;
  REQUIRED DOUBLE contour_error_mm;";

/// What the program's columns hold.
const PATH_COLUMNS: &str = "; x_mm, x_d_mm: the axis's true and desired position through its \
transmission [mm] (NaN for an axis that drives no machine axis; ringsync.machine says which it \
drives); contour_error_mm: the cycle's contour error [mm], the same on each of its rows (NaN \
where the path table has no such cycle)";

/// Writes `r`'s trace as Parquet to `w` (see the module docs); a part program's run adds
/// `x_mm`, `x_d_mm` and `contour_error_mm`.
pub fn write_trace_parquet(r: &RunResult, w: impl Write + Send) -> std::io::Result<()> {
    write(&r.trace, r.path.as_ref(), &r.scenario, ROW_GROUP_ROWS, w).map_err(|e| match e {
        ParquetError::External(inner) => match inner.downcast::<std::io::Error>() {
            Ok(io) => *io,
            Err(other) => std::io::Error::other(other),
        },
        other => std::io::Error::other(other),
    })
}

/// Each trace cycle's row in the path table (by time: both hold the cycle starts), or
/// `None`.
fn path_rows(trace: &Trace, path: &ringsync_model::contour::PathTrace) -> Vec<Option<usize>> {
    let mut j = 0;
    trace
        .t
        .iter()
        .map(|&t| {
            while j < path.t.len() && path.t[j] < t - 1e-7 {
                j += 1;
            }
            (j < path.t.len() && (path.t[j] - t).abs() <= 1e-7).then_some(j)
        })
        .collect()
}

/// Writes `trace` (and a part program's columns) with row groups of at most `rg_rows`
/// rows (whole cycles, one at least).
fn write(
    trace: &Trace,
    path: Option<&ringsync_model::contour::PathResult>,
    scenario: &str,
    rg_rows: usize,
    w: impl Write + Send,
) -> Result<(), ParquetError> {
    let schema_text = match path {
        Some(_) => format!(
            "{}{PATH_SCHEMA}\n}}",
            SCHEMA.trim_end().trim_end_matches('}')
        ),
        None => SCHEMA.to_string(),
    };
    let schema = Arc::new(parse_message_type(&schema_text)?);
    let mut meta = vec![
        KeyValue::new("ringsync.scenario".into(), scenario.to_string()),
        KeyValue::new(
            "ringsync.columns".into(),
            format!(
                "{COLUMNS}{}",
                if path.is_some() { PATH_COLUMNS } else { "" }
            ),
        ),
    ];
    if let Some(p) = path {
        let m: Vec<String> = p
            .drives
            .iter()
            .enumerate()
            .map(|(i, d)| match d {
                Some((name, k)) => format!(
                    "axis {} drives {name} ({:.6} mm/rev)",
                    i + 1,
                    std::f64::consts::TAU / k
                ),
                None => format!("axis {} drives no machine axis", i + 1),
            })
            .collect();
        meta.push(KeyValue::new("ringsync.machine".into(), m.join("; ")));
    }
    let rows_of = path.map(|p| path_rows(trace, &p.trace));
    let props = WriterProperties::builder()
        .set_compression(Compression::SNAPPY)
        // Doubles of a simulation hardly repeat: plain encoding; the axis column repeats.
        .set_dictionary_enabled(false)
        .set_column_dictionary_enabled("axis".into(), true)
        .set_created_by(format!("ringsync {}", env!("CARGO_PKG_VERSION")))
        .set_key_value_metadata(Some(meta))
        .build();
    let mut file = SerializedFileWriter::new(w, schema, Arc::new(props))?;
    let n = trace.axes.max(1);
    // Whole cycles per row group.
    let groups_per_rg = (rg_rows / n).max(1);
    let cycles = trace.t.len();
    let mut doubles: Vec<f64> = Vec::new();
    let mut axes: Vec<i32> = Vec::new();
    // One row group at least: an empty trace is a valid file with its columns.
    for g0 in (0..cycles.max(1)).step_by(groups_per_rg) {
        let g1 = (g0 + groups_per_rg).min(cycles);
        let rows = (g0 * n)..(g1 * n).min(trace.len());
        let mut rg = file.next_row_group()?;
        let mut c = 0;
        while let Some(mut col) = rg.next_column()? {
            if c == 1 {
                axes.clear();
                axes.extend(rows.clone().map(|i| (i % n + 1) as i32));
                col.typed::<Int32Type>().write_batch(&axes, None, None)?;
            } else {
                let values: &[f64] = match c {
                    0 => {
                        doubles.clear();
                        doubles.extend(
                            trace.t[g0..g1]
                                .iter()
                                .flat_map(|t| std::iter::repeat_n(*t, n)),
                        );
                        doubles.truncate(rows.len());
                        &doubles
                    }
                    2 => &trace.x_d[rows.clone()],
                    3 => &trace.x[rows.clone()],
                    4 => {
                        trace.e_into(rows.clone(), &mut doubles);
                        &doubles
                    }
                    5 => &trace.eps[rows.clone()],
                    6 => &trace.u[rows.clone()],
                    7 => &trace.sample_time[rows.clone()],
                    8 => &trace.apply_time[rows.clone()],
                    9 => &trace.clock_error_ns[rows.clone()],
                    10 | 11 => {
                        // The axis's position through its transmission [mm].
                        let col = if c == 10 { &trace.x } else { &trace.x_d };
                        doubles.clear();
                        doubles.extend(rows.clone().map(|i| {
                            match path.and_then(|p| p.drives.get(i % n).copied().flatten()) {
                                Some((_, k)) => col[i] / k,
                                None => f64::NAN,
                            }
                        }));
                        &doubles
                    }
                    _ => {
                        doubles.clear();
                        doubles.extend(rows.clone().map(|i| {
                            match (path, rows_of.as_ref().and_then(|r| r[i / n])) {
                                (Some(p), Some(j)) => p.trace.contour[j],
                                _ => f64::NAN,
                            }
                        }));
                        &doubles
                    }
                };
                col.typed::<DoubleType>().write_batch(values, None, None)?;
            }
            col.close()?;
            c += 1;
        }
        rg.close()?;
    }
    file.close()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use ::parquet::file::reader::{FileReader, SerializedFileReader};
    use ::parquet::record::Field;

    fn trace(axes: usize, cycles: usize) -> Trace {
        let mut t = Trace::with_capacity(axes, cycles);
        for g in 0..cycles {
            t.t.push(g as f64 * 1e-3);
            for a in 0..axes {
                let v = (g * axes + a) as f64;
                t.x_d.push(v + 0.1);
                t.x.push(v + 0.2);
                t.eps.push(v * 1e-9);
                t.u.push(-v);
                t.sample_time.push(v + 0.5);
                t.apply_time.push(if a == 1 { f64::NAN } else { v + 0.7 });
                t.clock_error_ns.push(a as f64);
            }
        }
        t
    }

    /// A reader of `bytes` (through a file: the crate reads files and its own buffers).
    fn reader(bytes: &[u8], name: &str) -> SerializedFileReader<std::fs::File> {
        let p =
            std::env::temp_dir().join(format!("ringsync-{name}-{}.parquet", std::process::id()));
        std::fs::write(&p, bytes).expect("a temporary file");
        let f = std::fs::File::open(&p).expect("opens");
        let _ = std::fs::remove_file(&p);
        SerializedFileReader::new(f).expect("a Parquet file")
    }

    fn read_back(bytes: Vec<u8>) -> (Vec<Vec<f64>>, usize) {
        let r = reader(&bytes, "exact");
        let groups = r.metadata().num_row_groups();
        let rows = r
            .get_row_iter(None)
            .expect("rows")
            .map(|row| {
                row.expect("row")
                    .get_column_iter()
                    .map(|(_, f)| match f {
                        Field::Double(v) => *v,
                        Field::Int(v) => f64::from(*v),
                        other => panic!("{other:?}"),
                    })
                    .collect()
            })
            .collect();
        (rows, groups)
    }

    /// Every value comes back exactly, row by row in trace.csv's order, NaN included, across
    /// row groups that split the run at whole cycles.
    #[test]
    fn the_trace_comes_back_exactly() {
        let tr = trace(3, 2000);
        let mut bytes = Vec::new();
        // 1000 rows a group: 333 whole cycles each, so 7 groups, the last of two cycles.
        write(&tr, None, "test", 1000, &mut bytes).expect("written");
        let (rows, groups) = read_back(bytes);
        assert_eq!(groups, 7);
        assert_eq!(rows.len(), tr.len());
        for (i, row) in rows.iter().enumerate() {
            let want = tr.row(i);
            let want = [
                want.t,
                want.axis as f64,
                want.x_d,
                want.x,
                want.e,
                want.eps,
                want.u,
                want.sample_time,
                want.apply_time,
                want.clock_error_ns,
            ];
            for (got, want) in row.iter().zip(want) {
                assert!(
                    got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                    "row {i}: {row:?} vs {want:?}"
                );
            }
        }
    }

    /// A run without a trace row still gives a valid file with the columns.
    #[test]
    fn an_empty_trace_is_a_valid_file() {
        let mut bytes = Vec::new();
        write(
            &Trace::with_capacity(4, 0),
            None,
            "empty",
            ROW_GROUP_ROWS,
            &mut bytes,
        )
        .expect("written");
        let r = reader(&bytes, "empty");
        assert_eq!(r.metadata().file_metadata().num_rows(), 0);
        assert_eq!(
            r.metadata().file_metadata().schema_descr().num_columns(),
            10
        );
    }
}
