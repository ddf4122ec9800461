//! Integration tests of the trajectory record: exact CSV header, bit-exact write/read round
//! trip, streaming writer equal to the in-memory writer, reader errors, no allocation.

use std::path::{Path, PathBuf};

use rand::RngExt;
use softcbf::record::{Columns, CsvWriter, Record, RecordError, Row};

use softcbf_tests::TestRng;
use softcbf_tests::alloc::{CountingAlloc, allocations};

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

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

#[test]
fn header_of_the_paper_robot_is_exact() {
    let record = Record::with_capacity(6, 12, &[], 0).unwrap();
    let expected = "t,q0,q1,q2,q3,q4,q5,qd0,qd1,qd2,qd3,qd4,qd5,\
                    tau0,tau1,tau2,tau3,tau4,tau5,taunom0,taunom1,taunom2,taunom3,taunom4,taunom5,\
                    b0,b1,b2,b3,b4,b5,b6,b7,b8,b9,b10,b11";
    assert_eq!(record.columns().header(), expected);
    let mut text = Vec::new();
    record.write_csv_to(&mut text).unwrap();
    assert_eq!(String::from_utf8(text).unwrap(), format!("{expected}\n"));
    assert_eq!(record.columns().width(), 37);
}

#[test]
fn header_with_extra_columns_is_exact() {
    let columns = Columns::new(6, 12, &["loop_us", "overrun", "clamps"]).unwrap();
    let expected = "t,q0,q1,q2,q3,q4,q5,qd0,qd1,qd2,qd3,qd4,qd5,\
                    tau0,tau1,tau2,tau3,tau4,tau5,taunom0,taunom1,taunom2,taunom3,taunom4,taunom5,\
                    b0,b1,b2,b3,b4,b5,b6,b7,b8,b9,b10,b11,loop_us,overrun,clamps";
    assert_eq!(columns.header(), expected);
    let small = Columns::new(1, 2, &["x"]).unwrap();
    assert_eq!(small.header(), "t,q0,qd0,tau0,taunom0,b0,b1,x");
    for (k, name) in expected.split(',').enumerate() {
        assert_eq!(columns.name(k).as_deref(), Some(name));
        assert_eq!(columns.index_of(name), Some(k));
    }
    assert_eq!(columns.name(40), None);
}

#[test]
fn extra_names_are_validated() {
    for bad in ["", "q3", "b0", "t", "taunom5", "a,b", "μs", "x y"] {
        let error = Columns::new(6, 12, &[bad]).unwrap_err();
        assert!(
            matches!(error, RecordError::ExtraName { .. }),
            "`{bad}` accepted"
        );
    }
    assert!(Columns::new(6, 12, &["clamps", "clamps"]).is_err());
    // Names that only look like standard ones are fine.
    assert!(Columns::new(6, 12, &["q", "bx", "tau_max", "b0_raw", "loop_us"]).is_ok());
}

#[test]
fn rows_are_stored_and_read_back_by_field() {
    let mut record = Record::with_capacity(2, 3, &["loop_us"], 4).unwrap();
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
        "t,q0,q1,qd0,qd1,tau0,tau1,taunom0,taunom1,b0,b1,b2,loop_us\n\
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
        (6, 12, vec!["loop_us", "overrun", "clamps"], 2),
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
        "t,q0,qd0,tau0,taunom0\n0.1,-0.08,1e-7,1e300,-0\n"
    );
}

#[test]
fn streaming_writer_matches_in_memory_writer() {
    let extra = ["loop_us", "overrun", "clamps"];
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
    let good = "t,q0,q1,qd0,qd1,tau0,tau1,taunom0,taunom1,b0,loop_us\n0,1,2,3,4,5,6,7,8,9,10\n";
    let record = Record::parse_csv(good, Path::new("log.csv")).unwrap();
    assert_eq!((record.columns().n(), record.columns().m()), (2, 1));
    assert_eq!(record.columns().extra_names(), ["loop_us"]);

    let bad_number = format!("{good}0.001,1,2,3,4,5,6,7,8,9,10\n0.002,1,2,3,4,5,x7,7,8,9,10\n");
    assert_eq!(
        parse_error(&bad_number),
        "log.csv:4: column `tau1`: `x7` is not a number"
    );
    let short = format!("{good}0.001,1,2\n");
    assert_eq!(
        parse_error(&short),
        "log.csv:3: 3 fields, the header has 11"
    );
    assert_eq!(
        parse_error(""),
        "log.csv:1: empty file, expected the header `t,q0,…`"
    );
    assert_eq!(
        parse_error("time,q0\n"),
        "log.csv:1: column 1 is `time`, expected `t`"
    );
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

#[test]
fn push_row_does_not_allocate_within_capacity() {
    let (n, m, rows) = (6, 12, 2000);
    let mut record = Record::with_capacity(n, m, &["loop_us", "overrun", "clamps"], rows).unwrap();
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
