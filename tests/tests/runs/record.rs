//! Integration tests of the trajectory record: exact CSV header named after the model,
//! names a CSV reader (and Python's `csv`) takes as they are, bit-exact write/read round
//! trip, old headers still read, streaming writer equal to the in-memory writer, reader
//! errors, no allocation.

use std::path::{Path, PathBuf};

use rand::RngExt;
use softcbf::model::Model;
use softcbf::record::{Columns, CsvWriter, Record, RecordError, Row};
use softcbf::robot_file::load_robot;

use softcbf_tests::TestRng;
use softcbf_tests::alloc::allocations;

fn temp_file(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("record-tests");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Values that stress the number format: signed zeros, subnormals, extremes, non-finite,
/// decimals without an exact binary form, and the switch points of the format (1e-5, 1e16).
const SPECIAL: [f64; 22] = [
    0.0,
    -0.0,
    f64::MIN_POSITIVE,
    5e-324,
    -2.2250738585072e-308,
    f64::EPSILON,
    f64::MAX,
    f64::MIN,
    1e-5,
    9.999999999999999e-6,
    1e16,
    9999999999999998.0,
    0.1 + 0.2,
    1.0 / 3.0,
    -0.08,
    123456.789e-12,
    f64::INFINITY,
    f64::NEG_INFINITY,
    f64::NAN,
    1.0,
    -1.5e300,
    7.0e-310,
];

/// A record of `rows` random rows; values mix random bit patterns, wide-range decimals
/// and [`SPECIAL`].
fn random_record(n: usize, m: usize, extra: &[&str], rows: usize, seed: u64) -> Record {
    let mut rng = softcbf_tests::rng(seed);
    let mut record = Record::with_capacity(n, m, extra, rows).unwrap();
    let width = record.columns().width();
    let value = |rng: &mut TestRng| match rng.random_range(0..4u32) {
        0 => f64::from_bits(rng.random::<u64>()),
        1 => SPECIAL[rng.random_range(0..SPECIAL.len())],
        2 => rng.random_range(-1.0..1.0) * 10f64.powi(rng.random_range(-20..20)),
        _ => rng.random_range(-0.2..0.2),
    };
    for _ in 0..rows {
        let v: Vec<f64> = (0..width).map(|_| value(&mut rng)).collect();
        let (t, rest) = v.split_first().unwrap();
        let (q, rest) = rest.split_at(n);
        let (qd, rest) = rest.split_at(n);
        let (tau, rest) = rest.split_at(n);
        let (tau_nom, rest) = rest.split_at(n);
        let (b, extra) = rest.split_at(m);
        record
            .push_row(&Row {
                t: *t,
                q,
                qd,
                tau,
                tau_nom,
                b,
                extra,
            })
            .unwrap();
    }
    record
}

/// Same bits, except that any NaN equals any NaN (the text form keeps no payload).
fn assert_same_values(a: &Record, b: &Record) {
    assert_eq!(a.columns(), b.columns());
    assert_eq!(a.len(), b.len());
    for (k, (x, y)) in a.values().iter().zip(b.values()).enumerate() {
        let same = x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan());
        assert!(
            same,
            "value {k}: wrote {x:e} ({:#x}), read {y:e} ({:#x})",
            x.to_bits(),
            y.to_bits()
        );
    }
}

/// The header of `softcbf simulate`'s `trajectory.csv` for the paper robot.
const PAPER_HEADER: &str = "t [s],\
    dx1 [m],dy1 [m],dL1 [m],dx2 [m],dy2 [m],dL2 [m],\
    dx1/dt [m/s],dy1/dt [m/s],dL1/dt [m/s],dx2/dt [m/s],dy2/dt [m/s],dL2/dt [m/s],\
    tau dx1 [N],tau dy1 [N],tau dL1 [N],tau dx2 [N],tau dy2 [N],tau dL2 [N],\
    tau_nom dx1 [N],tau_nom dy1 [N],tau_nom dL1 [N],tau_nom dx2 [N],tau_nom dy2 [N],tau_nom dL2 [N],\
    b module 1 corner 1 [m],b module 1 corner 2 [m],b module 1 corner 3 [m],\
    b module 1 corner 4 [m],b module 1 corner 5 [m],b module 1 corner 6 [m],\
    b module 2 corner 1 [m],b module 2 corner 2 [m],b module 2 corner 3 [m],\
    b module 2 corner 4 [m],b module 2 corner 5 [m],b module 2 corner 6 [m],\
    b module 1 elongation min [m],b module 1 elongation max [m],b module 1 bend [rad],\
    b module 2 elongation min [m],b module 2 elongation max [m],b module 2 bend [rad]";

fn paper_model() -> Model {
    Model::new(load_robot(None).unwrap()).unwrap()
}

#[test]
fn header_of_the_paper_robot_is_exact() {
    let model = paper_model();
    let columns = Columns::for_model(&model, &[]).unwrap();
    assert_eq!(columns.header(), PAPER_HEADER);
    // The barrier labels are the model's table's, in order.
    let table: Vec<&str> = model
        .generated
        .barrier_table()
        .iter()
        .map(|b| b.label)
        .collect();
    assert_eq!(columns.barrier_labels(), table);
    assert_eq!(
        columns.coordinate_names(),
        ["dx1", "dy1", "dL1", "dx2", "dy2", "dL2"]
    );
    let record = Record::for_columns(columns, 0);
    let mut text = Vec::new();
    record.write_csv_to(&mut text).unwrap();
    assert_eq!(
        String::from_utf8(text).unwrap(),
        format!("{PAPER_HEADER}\n")
    );
    // t, four groups of six, twelve corners and six limits.
    assert_eq!(record.columns().width(), 1 + 4 * 6 + 12 + 6);
    // Without a model: the same coordinate names, numbered barrier labels.
    let plain = Columns::new(6, 2, &[]).unwrap();
    assert!(
        plain
            .header()
            .starts_with("t [s],dx1 [m],dy1 [m],dL1 [m],dx2 [m]")
    );
    assert!(plain.header().ends_with(",b barrier 1 [m],b barrier 2 [m]"));
    assert_eq!(
        Columns::new(2, 0, &[]).unwrap().coordinate_names(),
        ["q1", "q2"]
    );
}

#[test]
fn header_with_extra_columns_is_exact() {
    let model = paper_model();
    let columns =
        Columns::for_model(&model, &["loop [us]", "overrun", "f module 1 tendon 1 [N]"]).unwrap();
    let expected = format!("{PAPER_HEADER},loop [us],overrun,f module 1 tendon 1 [N]");
    assert_eq!(columns.header(), expected);
    let small = Columns::named(&["x"], &["near", "far"], &["y [s]"]).unwrap();
    assert_eq!(
        small.header(),
        "t [s],x [m],x/dt [m/s],tau x [N],tau_nom x [N],b near [m],b far [m],y [s]"
    );
    for (k, name) in expected.split(',').enumerate() {
        assert_eq!(columns.name(k).as_deref(), Some(name));
        assert_eq!(columns.index_of(name), Some(k));
    }
    assert_eq!(columns.name(expected.split(',').count()), None);
}

#[test]
fn names_are_validated() {
    let refused = |coordinates: &[&str], barriers: &[&str], extra: &[&str]| match Columns::named(
        coordinates,
        barriers,
        extra,
    ) {
        Err(RecordError::ColumnName { what, .. }) => what,
        other => panic!("{coordinates:?} {barriers:?} {extra:?}: accepted: {other:?}"),
    };
    for bad in ["", "d x", "dx/1", "Δx1", "a,b", "x\"", "dx1 [m]"] {
        assert_eq!(refused(&[bad], &[], &[]), "coordinate name", "`{bad}`");
    }
    for bad in [
        "",
        " corner",
        "corner ",
        "a,b",
        "a\"b",
        "line\nbreak",
        "tab\there",
        "x [m]",
    ] {
        assert_eq!(refused(&["x"], &[bad], &[]), "barrier label", "`{bad}`");
    }
    for bad in [
        "",
        "a,b",
        "\"quoted\"",
        "x\ry",
        "b far [m]",
        "b module 1 corner 1 [m]",
    ] {
        assert_eq!(
            refused(&["x"], &["near"], &[bad]),
            "extra column name",
            "`{bad}`"
        );
    }
    // Every column name of the header is unique.
    assert_eq!(refused(&["x", "x"], &[], &[]), "coordinate name");
    assert_eq!(refused(&["x"], &["near", "near"], &[]), "barrier label");
    assert_eq!(
        refused(&["x"], &[], &["clamps", "clamps"]),
        "extra column name"
    );
    assert_eq!(refused(&["x"], &[], &["x [m]"]), "extra column name");
    assert_eq!(refused(&["x"], &[], &["t [s]"]), "extra column name");
    let error = Columns::named(&["x"], &[], &["tau x [N]"]).unwrap_err();
    assert_eq!(
        error.to_string(),
        "extra column name `tau x [N]`: it makes a column name that is given twice"
    );
    // Names that only look like standard ones, and labels in other scripts, are fine.
    assert!(
        Columns::named(
            &["dx1"],
            &["corner α"],
            &["q", "bx", "tau_max", "b0_raw", "t", "b x"]
        )
        .is_ok()
    );
}

#[test]
fn rows_are_stored_and_read_back_by_field() {
    let columns = Columns::named(&["a", "b"], &["one", "two", "three"], &["loop [us]"]).unwrap();
    let mut record = Record::for_columns(columns, 4);
    for k in 0..3 {
        let s = k as f64;
        record
            .push_row(&Row {
                t: 0.001 * s,
                q: &[1.0 + s, 2.0 + s],
                qd: &[3.0 + s, 4.0 + s],
                tau: &[5.0 + s, 6.0 + s],
                tau_nom: &[7.0 + s, 8.0 + s],
                b: &[9.0 + s, 10.0 + s, 11.0 + s],
                extra: &[12.0 + s],
            })
            .unwrap();
    }
    assert_eq!(record.len(), 3);
    assert_eq!(record.times().collect::<Vec<_>>(), [0.0, 0.001, 0.002]);
    assert_eq!(record.q(1).collect::<Vec<_>>(), [2.0, 3.0, 4.0]);
    assert_eq!(record.qd(0).collect::<Vec<_>>(), [3.0, 4.0, 5.0]);
    assert_eq!(record.tau(1).collect::<Vec<_>>(), [6.0, 7.0, 8.0]);
    assert_eq!(record.tau_nom(0).collect::<Vec<_>>(), [7.0, 8.0, 9.0]);
    assert_eq!(record.b(2).collect::<Vec<_>>(), [11.0, 12.0, 13.0]);
    assert_eq!(record.column(12).collect::<Vec<_>>(), [12.0, 13.0, 14.0]);
    assert_eq!(record.b(3).count(), 0);
    assert_eq!(record.column(13).count(), 0);
    assert_eq!(record.row(2).unwrap().extra, [14.0]);
    assert!(record.row(3).is_none());
    let text = {
        let mut out = Vec::new();
        record.write_csv_to(&mut out).unwrap();
        String::from_utf8(out).unwrap()
    };
    assert_eq!(
        text,
        "t [s],a [m],b [m],a/dt [m/s],b/dt [m/s],tau a [N],tau b [N],tau_nom a [N],tau_nom b [N],\
         b one [m],b two [m],b three [m],loop [us]\n\
         0,1,2,3,4,5,6,7,8,9,10,11,12\n\
         0.001,2,3,4,5,6,7,8,9,10,11,12,13\n\
         0.002,3,4,5,6,7,8,9,10,11,12,13,14\n"
    );
}

#[test]
fn wrong_row_sizes_are_refused() {
    let mut record = Record::with_capacity(2, 1, &[], 4).unwrap();
    let row = Row {
        t: 0.0,
        q: &[0.0, 0.0],
        qd: &[0.0, 0.0],
        tau: &[0.0],
        tau_nom: &[0.0, 0.0],
        b: &[0.0],
        extra: &[],
    };
    match record.push_row(&row) {
        Err(RecordError::RowSize {
            field: "tau",
            expected: 2,
            found: 1,
        }) => {}
        other => panic!("expected a tau size error, got {other:?}"),
    }
    assert!(record.is_empty());
}

#[test]
fn csv_round_trip_is_bit_exact() {
    for (n, m, extra, seed) in [
        (6, 12, vec![], 1),
        (
            6,
            12,
            vec!["loop [us]", "overrun", "f module 1 tendon 1 [N]"],
            2,
        ),
        (1, 0, vec![], 3),
        (3, 6, vec!["x"], 4),
    ] {
        let record = random_record(n, m, &extra, 500, seed);
        let path = temp_file(&format!("round-trip-{seed}.csv"));
        record.write_csv(&path).unwrap();
        let back = Record::read_csv(&path).unwrap();
        assert_same_values(&record, &back);
        // Every special value is written in its shortest form and read back exactly.
        for &x in &SPECIAL {
            let mut one = Record::with_capacity(1, 0, &[], 1).unwrap();
            let v = [x];
            one.push_row(&Row {
                t: x,
                q: &v,
                qd: &v,
                tau: &v,
                tau_nom: &v,
                b: &[],
                extra: &[],
            })
            .unwrap();
            let mut text = Vec::new();
            one.write_csv_to(&mut text).unwrap();
            let back =
                Record::parse_csv(std::str::from_utf8(&text).unwrap(), Path::new("mem")).unwrap();
            assert_same_values(&one, &back);
        }
    }
}

#[test]
fn numbers_are_short() {
    let mut record = Record::with_capacity(1, 0, &[], 1).unwrap();
    let row = Row {
        t: 0.1,
        q: &[-0.08],
        qd: &[1e-7],
        tau: &[1e300],
        tau_nom: &[-0.0],
        b: &[],
        extra: &[],
    };
    record.push_row(&row).unwrap();
    let mut text = Vec::new();
    record.write_csv_to(&mut text).unwrap();
    assert_eq!(
        String::from_utf8(text).unwrap(),
        "t [s],q1 [m],q1/dt [m/s],tau q1 [N],tau_nom q1 [N]\n0.1,-0.08,1e-7,1e300,-0\n"
    );
}

#[test]
fn streaming_writer_matches_in_memory_writer() {
    let extra = ["loop [us]", "overrun", "clamps"];
    let record = random_record(6, 12, &extra, 300, 7);
    let mut in_memory = Vec::new();
    record.write_csv_to(&mut in_memory).unwrap();

    let mut stream =
        CsvWriter::new(Vec::new(), record.columns().clone(), Path::new("mem")).unwrap();
    for row in record.rows() {
        stream.push_row(&row).unwrap();
    }
    stream.flush().unwrap();
    assert_eq!(stream.rows(), 300);
    assert_eq!(stream.get_ref(), &in_memory);

    // To a file, dropped without `finish`: every row is there.
    let path = temp_file("stream-dropped.csv");
    {
        let mut stream = CsvWriter::create(&path, record.columns().clone()).unwrap();
        for row in record.rows() {
            stream.push_row(&row).unwrap();
        }
    }
    assert_eq!(std::fs::read(&path).unwrap(), in_memory);
    assert_same_values(&record, &Record::read_csv(&path).unwrap());

    // Every row pushed is in the file at once, whole, while the writer stays open (no
    // flush): a run killed between two rows leaves a complete log.
    let path = temp_file("stream-open.csv");
    let mut stream = CsvWriter::create(&path, record.columns().clone()).unwrap();
    for (k, row) in record.rows().take(10).enumerate() {
        stream.push_row(&row).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.ends_with('\n'), "row {k} is not whole in the file");
        assert_eq!(Record::read_csv(&path).unwrap().len(), k + 1);
    }
    std::mem::forget(stream); // as if the process died here: nothing more is written
    assert_eq!(Record::read_csv(&path).unwrap().len(), 10);
}

/// The error message of parsing `text` (as file `log.csv`).
fn parse_error(text: &str) -> String {
    let error = Record::parse_csv(text, Path::new("log.csv")).unwrap_err();
    error.to_string()
}

#[test]
fn reader_errors_name_file_line_and_column() {
    let header = "t [s],a [m],b [m],a/dt [m/s],b/dt [m/s],tau a [N],tau b [N],tau_nom a [N],\
                  tau_nom b [N],b near [m],loop [us]";
    let good = format!("{header}\n0,1,2,3,4,5,6,7,8,9,10\n");
    let record = Record::parse_csv(&good, Path::new("log.csv")).unwrap();
    assert_eq!((record.columns().n(), record.columns().m()), (2, 1));
    assert_eq!(record.columns().coordinate_names(), ["a", "b"]);
    assert_eq!(record.columns().barrier_labels(), ["near"]);
    assert_eq!(record.columns().extra_names(), ["loop [us]"]);

    let bad_number = format!("{good}0.001,1,2,3,4,5,6,7,8,9,10\n0.002,1,2,3,4,5,x7,7,8,9,10\n");
    assert_eq!(
        parse_error(&bad_number),
        "log.csv:4: column `tau b [N]`: `x7` is not a number"
    );
    let short = format!("{good}0.001,1,2\n");
    assert_eq!(
        parse_error(&short),
        "log.csv:3: 3 fields, the header has 11"
    );
    assert_eq!(
        parse_error(""),
        "log.csv:1: empty file, expected the header `t [s],…`"
    );
    assert_eq!(
        parse_error("time,q0\n"),
        "log.csv:1: column 1 is `time`, expected `t [s]` (or `t` in logs written before the \
         named columns)"
    );
    // A velocity column missing: the first column out of place is named.
    let missing_qd = "t [s],a [m],b [m],a/dt [m/s],tau a [N],tau b [N]\n";
    assert_eq!(
        parse_error(missing_qd),
        "log.csv:1: column 5 is `tau a [N]`, expected `b/dt [m/s]` (n = 2 from the coordinate \
         columns)"
    );
    let swapped =
        "t [s],a [m],b [m],a/dt [m/s],b/dt [m/s],tau b [N],tau a [N],tau_nom a [N],tau_nom b [N]\n";
    assert!(
        parse_error(swapped)
            .starts_with("log.csv:1: column 6 is `tau b [N]`, expected `tau a [N]`"),
        "{}",
        parse_error(swapped)
    );
    let no_velocities = "t [s],a [m],b [m]\n";
    assert!(
        parse_error(no_velocities).starts_with(
            "log.csv:1: column 4 is `<end of line>`, expected the velocity column `a/dt [m/s]`"
        ),
        "{}",
        parse_error(no_velocities)
    );
    let bad_coordinate = "t [s],a b [m],a b/dt [m/s],tau a b [N],tau_nom a b [N]\n";
    assert!(
        parse_error(bad_coordinate).starts_with(
            "log.csv:1: column 2 is `a b [m]`, expected a valid column name (coordinate name `a b`"
        ),
        "{}",
        parse_error(bad_coordinate)
    );
    let twice = format!("{header},loop [us]\n");
    assert!(
        parse_error(&twice).starts_with("log.csv:1: column 12 is `loop [us]`, expected a valid column name (extra column name `loop [us]`: it makes a column name that is given twice)"),
        "{}",
        parse_error(&twice)
    );

    // A file on disk: the path is named; a missing file is an I/O error naming it.
    let path = temp_file("bad.csv");
    std::fs::write(&path, &bad_number).unwrap();
    let message = Record::read_csv(&path).unwrap_err().to_string();
    assert!(
        message.starts_with(&format!("{}:4:", path.display())),
        "{message}"
    );
    let missing = temp_file("does-not-exist.csv");
    let message = Record::read_csv(&missing).unwrap_err().to_string();
    assert!(
        message.starts_with(&missing.display().to_string()),
        "{message}"
    );

    // CRLF line ends and a trailing empty line are accepted.
    let crlf = good.replace('\n', "\r\n") + "\r\n";
    assert_same_values(
        &record,
        &Record::parse_csv(&crlf, Path::new("log.csv")).unwrap(),
    );
}

/// Logs written before the columns were named (`t,q0,…`) are still read: the same values,
/// the standard coordinate names and numbered barrier labels; written again, they get the
/// new header.
#[test]
fn old_headers_are_still_read() {
    let old = "t,q0,q1,q2,qd0,qd1,qd2,tau0,tau1,tau2,taunom0,taunom1,taunom2,b0,b1,loop_us\n\
               0,1,2,3,4,5,6,7,8,9,10,11,12,13,14,15\n\
               0.001,1,2,3,4,5,6,7,8,9,10,11,12,NaN,-inf,16\n";
    let record = Record::parse_csv(old, Path::new("old.csv")).unwrap();
    assert_eq!(record.len(), 2);
    assert_eq!(record.columns().coordinate_names(), ["dx1", "dy1", "dL1"]);
    assert_eq!(
        record.columns().barrier_labels(),
        ["barrier 1", "barrier 2"]
    );
    assert_eq!(record.columns().extra_names(), ["loop_us"]);
    assert_eq!(record.tau_nom(2).collect::<Vec<_>>(), [12.0, 12.0]);
    assert_eq!(record.b(1).nth(1), Some(f64::NEG_INFINITY));
    assert_eq!(record.column(15).collect::<Vec<_>>(), [15.0, 16.0]);
    let mut text = Vec::new();
    record.write_csv_to(&mut text).unwrap();
    let text = String::from_utf8(text).unwrap();
    assert!(
        text.starts_with("t [s],dx1 [m],dy1 [m],dL1 [m],dx1/dt [m/s]"),
        "{text}"
    );
    assert_same_values(
        &record,
        &Record::parse_csv(&text, Path::new("new.csv")).unwrap(),
    );

    // The old header's errors still name the column.
    let missing_qd = "t,q0,q1,qd0,tau0,tau1,taunom0,taunom1\n";
    assert_eq!(
        parse_error(missing_qd),
        "log.csv:1: column 5 is `tau0`, expected `qd1` (n = 2 from the q columns)"
    );
    let bad_extra = "t,q0,qd0,tau0,taunom0,b0,b2\n";
    assert!(
        parse_error(bad_extra).starts_with("log.csv:1: column 7 is `b2`"),
        "{}",
        parse_error(bad_extra)
    );
}

/// Splits one CSV line by the rules of RFC 4180 (fields separated by commas; a field in
/// double quotes may hold commas and doubled quotes). Returns the fields and whether any
/// needed quoting.
fn rfc4180_fields(line: &str) -> (Vec<String>, bool) {
    let (mut fields, mut field, mut quoted) = (Vec::new(), String::new(), false);
    let mut any_quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', false) if field.is_empty() => (quoted, any_quoted) = (true, true),
            ('"', true) if chars.peek() == Some(&'"') => {
                chars.next();
                field.push('"');
            }
            ('"', true) => quoted = false,
            (',', false) => fields.push(std::mem::take(&mut field)),
            (c, _) => field.push(c),
        }
    }
    fields.push(field);
    (fields, any_quoted)
}

/// The header a spreadsheet or pandas reads: one line, split by the CSV rules into exactly
/// the column names, none quoted, all unique, the standard ones ASCII; the data lines into
/// as many fields, each a number `float()` reads.
#[test]
fn headers_read_as_plain_csv() {
    let model = paper_model();
    let names =
        softcbf::hardware::run_loop::extra_columns(6, &softcbf::record::coordinate_names(6));
    let columns = Columns::for_model(&model, &softcbf::record::as_strs(&names)).unwrap();
    let header = columns.header();
    let (fields, quoted) = rfc4180_fields(&header);
    assert!(!quoted, "no name needs quoting: {header}");
    assert_eq!(fields.len(), columns.width());
    for (k, field) in fields.iter().enumerate() {
        assert_eq!(Some(field.as_str()), columns.name(k).as_deref());
        assert!(
            field.is_ascii() && !field.is_empty() && field.trim() == field,
            "`{field}`"
        );
    }
    let mut unique = fields.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), fields.len(), "duplicate names in {header}");
    for expected in [
        "t [s]",
        "dx1 [m]",
        "dL2/dt [m/s]",
        "tau dy1 [N]",
        "tau_nom dL2 [N]",
        "b module 2 corner 6 [m]",
        "read [us]",
        "f module 2 tendon 3 [N]",
        "qpred dL2 [m]",
    ] {
        assert!(
            fields.iter().any(|f| f == expected),
            "no `{expected}` in {header}"
        );
    }

    // A whole file: every data line splits into as many plain fields.
    let record = random_record(6, 12, &[], 20, 9);
    let mut text = Vec::new();
    record.write_csv_to(&mut text).unwrap();
    for line in String::from_utf8(text).unwrap().lines().skip(1) {
        let (fields, quoted) = rfc4180_fields(line);
        assert!(!quoted && fields.len() == 37, "{line}");
    }
}

/// Python's `csv` module (what pandas's reader follows) reads the header into the expected
/// names and the rows into numbers; skipped where `python3` is not installed.
#[test]
fn python_csv_reads_the_names() {
    let Ok(probe) = std::process::Command::new("python3")
        .args(["-c", "import csv"])
        .output()
    else {
        eprintln!("python3 not found: skipped");
        return;
    };
    if !probe.status.success() {
        eprintln!("python3 without csv: skipped");
        return;
    }
    let model = paper_model();
    let columns = Columns::for_model(&model, &["read [us]", "f module 1 tendon 1 [N]"]).unwrap();
    let mut record = Record::for_columns(columns.clone(), 2);
    let v = vec![0.25; 6];
    let b = vec![f64::NAN; model.nb()];
    record
        .push_row(&Row {
            t: 0.001,
            q: &v,
            qd: &v,
            tau: &v,
            tau_nom: &v,
            b: &b,
            extra: &[850.0, f64::INFINITY],
        })
        .unwrap();
    let path = temp_file("python.csv");
    record.write_csv(&path).unwrap();
    let script = r#"
import csv, json, math, sys
with open(sys.argv[1], newline="", encoding="utf-8") as f:
    rows = list(csv.DictReader(f))
row = rows[0]
values = {k: float(v) for k, v in row.items()}
print(json.dumps({"names": list(row.keys()), "rows": len(rows),
                  "dx1": values["dx1 [m]"], "read": values["read [us]"],
                  "nan": math.isnan(values["b module 2 corner 6 [m]"]),
                  "inf": math.isinf(values["f module 1 tendon 1 [N]"])}))
"#;
    let output = std::process::Command::new("python3")
        .args(["-c", script])
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let answer: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let names: Vec<String> = (0..columns.width())
        .filter_map(|k| columns.name(k))
        .collect();
    assert_eq!(answer["names"], serde_json::json!(names));
    assert_eq!(answer["rows"], 1);
    assert_eq!(answer["dx1"], 0.25);
    assert_eq!(answer["read"], 850.0);
    assert_eq!(answer["nan"], true);
    assert_eq!(answer["inf"], true);
}

#[test]
fn relabel_keeps_values_and_checks_sizes() {
    let model = paper_model();
    let mut record = random_record(6, model.nb(), &["x"], 5, 12);
    let before = record.clone();
    record
        .relabel(Columns::for_model(&model, &["x"]).unwrap())
        .unwrap();
    assert_eq!(record.values().len(), before.values().len());
    assert!(
        record
            .values()
            .iter()
            .zip(before.values())
            .all(|(a, b)| a.to_bits() == b.to_bits())
    );
    assert_eq!(record.columns().barrier_labels()[11], "module 2 corner 6");
    let nb = model.nb();
    let error = record
        .relabel(Columns::new(6, nb - 1, &["x"]).unwrap())
        .unwrap_err();
    assert_eq!(
        error.to_string(),
        format!(
            "the new columns have {} barriers, the record has {nb}",
            nb - 1
        )
    );
    assert!(record.relabel(Columns::new(6, nb, &[]).unwrap()).is_err());
    assert_eq!(record.columns().barrier_labels()[11], "module 2 corner 6");
}

#[test]
fn push_row_does_not_allocate_within_capacity() {
    let (n, m, rows) = (6, 12, 2000);
    let mut record =
        Record::with_capacity(n, m, &["loop [us]", "overrun", "clamps"], rows).unwrap();
    let q = vec![0.01; n];
    let b = vec![0.02; m];
    let extra = [12.5, 0.0, 1.0];
    let row_at = |t| Row {
        t,
        q: &q,
        qd: &q,
        tau: &q,
        tau_nom: &q,
        b: &b,
        extra: &extra,
    };
    let before = allocations();
    for k in 0..rows {
        record.push_row(&row_at(k as f64 * 1e-3)).unwrap();
    }
    assert_eq!(
        allocations() - before,
        0,
        "push_row allocated within capacity"
    );
    assert_eq!(record.len(), rows);

    // Beyond capacity the record still grows (and the counter sees it).
    let row = row_at(9.0);
    let before = allocations();
    record.push_row(&row).unwrap();
    assert!(allocations() > before);
    assert_eq!(record.len(), rows + 1);

    // The streaming writer does not allocate per row either.
    let mut stream =
        CsvWriter::new(std::io::sink(), record.columns().clone(), Path::new("sink")).unwrap();
    let before = allocations();
    for row in record.rows() {
        stream.push_row(&row).unwrap();
    }
    stream.flush().unwrap();
    assert_eq!(allocations() - before, 0, "CsvWriter::push_row allocated");
}
