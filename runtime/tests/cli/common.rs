//! What the end-to-end tests of the `softcbf` binary share: the binary, the hardware
//! example, temporary folders, `softcbf emulate` in the background, and an independent
//! Protocol 2.0 reader (its own packets and CRC, written from the e-Manual).
// Each test binary uses part of this module.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{Receiver, channel};
use std::thread;
use std::time::{Duration, Instant};

/// The `softcbf` binary under test.
pub const BIN: &str = env!("CARGO_BIN_EXE_softcbf");

/// `robots/hardware-example.toml` of the checkout.
pub fn robot() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/hardware-example.toml")
}

/// A fresh folder `name` under the system's temporary folder, for this process.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("softcbf-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Waits at most `limit` for `child`; kills it (and fails) beyond.
pub fn wait_for(child: &mut Child, limit: Duration, what: &str) -> ExitStatus {
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{what}: still running after {limit:?}");
        }
        thread::sleep(Duration::from_millis(20));
    }
}

/// Lines of a child's output, read by a thread.
pub fn lines_of(stream: impl Read + Send + 'static) -> Receiver<String> {
    let (tx, rx) = channel();
    thread::spawn(move || {
        for line in BufReader::new(stream).lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    rx
}

/// Collects lines until one contains `needle` (or `limit` passes); returns all so far.
pub fn until(lines: &Receiver<String>, needle: &str, limit: Duration) -> Vec<String> {
    let deadline = Instant::now() + limit;
    let mut seen = Vec::new();
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        match lines.recv_timeout(left) {
            Ok(line) => {
                let done = line.contains(needle);
                seen.push(line);
                if done {
                    break;
                }
            }
            Err(_) => break,
        }
    }
    seen
}

/// `softcbf emulate` in the background, stopped with SIGTERM when dropped.
pub struct Emulator {
    /// Its process.
    pub child: Child,
    /// The pseudo-terminal it serves.
    pub port: String,
}

impl Emulator {
    /// Starts one for the hardware example with `extra` options.
    pub fn start(extra: &[&str]) -> Emulator {
        let mut child = Command::new(BIN)
            .arg("emulate")
            .arg("--robot")
            .arg(robot())
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("softcbf emulate starts");
        let lines = lines_of(child.stdout.take().unwrap());
        let seen = until(&lines, "port:", Duration::from_secs(60));
        let port = seen
            .iter()
            .find_map(|l| l.strip_prefix("port: "))
            .unwrap_or_else(|| panic!("no port announced: {seen:?}"))
            .to_string();
        // Keep draining its output so it never blocks on a full pipe.
        thread::spawn(move || for _ in lines {});
        Emulator { child, port }
    }
}

impl Drop for Emulator {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            let _ = Command::new("kill")
                .arg(self.child.id().to_string())
                .status();
            let _ = wait_for(&mut self.child, Duration::from_secs(10), "emulator");
        }
    }
}

// ---------------------------------------------------------------------------------------
// An independent Protocol 2.0 reader (e-Manual "Protocol 2.0"): CRC-16 with polynomial
// 0x8005, initial value 0, most significant bit first, over the packet up to the CRC.

pub fn crc(bytes: &[u8]) -> u16 {
    let mut crc: u16 = 0;
    for &byte in bytes {
        crc ^= u16::from(byte) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x8005
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// A READ instruction packet for `len` bytes at `address` of servo `id` (no stuffing is
/// needed: no parameter here contains FF FF FD).
pub fn read_packet(id: u8, address: u16, len: u16) -> Vec<u8> {
    let mut p = vec![0xFF, 0xFF, 0xFD, 0x00, id, 7, 0, 0x02];
    p.extend_from_slice(&address.to_le_bytes());
    p.extend_from_slice(&len.to_le_bytes());
    let c = crc(&p);
    p.extend_from_slice(&c.to_le_bytes());
    p
}

/// Reads `len` bytes at `address` of servo `id` over the port at `path`, trying a few times.
pub fn read_register(path: &str, id: u8, address: u16, len: u16) -> Vec<u8> {
    let mut port = serialport::new(path, 1_000_000)
        .timeout(Duration::from_millis(5))
        .open()
        .unwrap_or_else(|e| panic!("the reader cannot open {path}: {e}"));
    for _ in 0..5 {
        let _ = port.clear(serialport::ClearBuffer::Input);
        port.write_all(&read_packet(id, address, len)).unwrap();
        let want = 11 + usize::from(len);
        let mut reply = Vec::new();
        let deadline = Instant::now() + Duration::from_millis(300);
        while Instant::now() < deadline {
            let mut buf = [0u8; 64];
            match port.read(&mut buf) {
                Ok(n) => reply.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => panic!("reader: {e}"),
            }
            if let Some(start) = reply.windows(4).position(|w| w == [0xFF, 0xFF, 0xFD, 0x00])
                && reply.len() >= start + want
            {
                let p = &reply[start..start + want];
                let ok = p[4] == id
                    && p[7] == 0x55
                    && p[8] & 0x7F == 0
                    && crc(&p[..want - 2]) == u16::from_le_bytes([p[want - 2], p[want - 1]]);
                if ok {
                    return p[9..9 + usize::from(len)].to_vec();
                }
                break;
            }
        }
    }
    panic!("servo {id} did not answer a read of {len} bytes at {address}");
}

pub const TORQUE_ENABLE: u16 = 64;
pub const BUS_WATCHDOG: u16 = 98;
pub const GOAL_CURRENT: u16 = 102;
pub const PRESENT_CURRENT: u16 = 126;

/// A set point inside the safe set, for runs about the bus and the stop, not the barriers.
pub const INSIDE: &str = "0,0,-0.02,0,0,-0.01";

/// A `softcbf run` started in the background, its standard output read line by line.
pub struct RunProcess {
    /// Its process.
    pub child: Child,
    /// Its standard output (`None` when it goes elsewhere).
    pub stdout: Option<Receiver<String>>,
}

/// Options of a test's run that a loaded machine needs (CI shares its cores): missed
/// deadlines do not decide the verdict, and a reply may take up to 100 ms (the emulator,
/// starved, answers late), unless the test is about them and gives the option itself. An
/// idle machine keeps the deadlines and the file's 10 ms; the tests are about the stop,
/// the log, the bus check or the barriers.
pub const LOAD_TOLERANT: [[&str; 2]; 2] = [
    ["--max-overrun-fraction", "1"],
    ["--reply-timeout-ms", "100"],
];

/// [`LOAD_TOLERANT`]'s options that `given` does not give itself.
pub fn load_tolerant(given: &[&str]) -> Vec<&'static str> {
    LOAD_TOLERANT
        .iter()
        .filter(|[option, _]| !given.contains(option))
        .flatten()
        .copied()
        .collect()
}

/// Starts `softcbf run` on the hardware example against `port`, writing to `out`, with
/// [`LOAD_TOLERANT`] unless `extra` gives those options.
pub fn start_run(port: &str, out: &Path, extra: &[&str]) -> RunProcess {
    let overruns = load_tolerant(extra);
    let mut child = Command::new(BIN)
        .arg("run")
        .arg("--robot")
        .arg(robot())
        .args(["--port", port, "--out"])
        .arg(out)
        .args(extra)
        .args(overruns)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("softcbf run starts");
    let stdout = Some(lines_of(child.stdout.take().unwrap()));
    RunProcess { child, stdout }
}

/// Waits for the run to end; its exit code, standard output and standard error.
pub fn finish_run(run: RunProcess, what: &str) -> (i32, String, String) {
    finish_run_within(run, Duration::from_secs(60), what)
}

/// [`finish_run`], waiting at most `limit`.
pub fn finish_run_within(
    mut run: RunProcess,
    limit: Duration,
    what: &str,
) -> (i32, String, String) {
    let status = wait_for(&mut run.child, limit, what);
    let mut stderr = String::new();
    if let Some(mut e) = run.child.stderr.take() {
        let _ = e.read_to_string(&mut stderr);
    }
    // The reader ends at the end of the output, which the exit has reached.
    let stdout = run
        .stdout
        .map(|rx| rx.iter().collect::<Vec<_>>().join("\n"))
        .unwrap_or_default();
    assert!(
        !stderr.contains("panicked"),
        "{what}: the run panicked:\n{stderr}"
    );
    (status.code().unwrap_or(-1), stdout, stderr)
}

/// The words of the faults a machine loaded by other work causes rather than the code:
/// the loop below `--min-rate` or paused near the servos' Bus Watchdog, a torque-off the
/// starved emulator did not confirm in time (tests read the servos independently after).
pub const LOAD_FAULTS: [&str; 3] = [
    "below the minimum",
    "the loop paused",
    "torque-off not confirmed",
];

/// Whether a run's verdict line is `UNSAFE` for relaxed ticks alone. The example robot's
/// ±10 % `[uncertainty]` leaves the robust rows with no common point on a few ticks of a
/// run against the emulator (2 or 3 of the first ticks; 0 without the table), which makes
/// the run unsafe (a relaxed tick is not filtered); tests of something else (signals, lost
/// output) accept that verdict until the filter meets those rows (issue 29).
pub fn unsafe_only_by_relaxed_ticks(output: &str) -> bool {
    // The verdict line, or (standard output lost) the error line that repeats it.
    output
        .lines()
        .find_map(|line| {
            line.strip_prefix("verdict: UNSAFE: ")
                .or_else(|| line.strip_prefix("error: unsafe run: "))
        })
        .is_some_and(|why| {
            why.split("; ")
                .all(|reason| reason.contains("ticks relaxed barrier rows"))
        })
}

/// Whether a run's status `code` is `expected`. A stop on one of the [`LOAD_FAULTS`] (exit
/// status 4, its words in `output`: the run's standard output and error) is printed as a
/// loaded machine's and answers `false`: the test then checks only what holds at any load.
/// So is a run unsafe by relaxed ticks alone ([`unsafe_only_by_relaxed_ticks`]) where a
/// test expects another status. Any other status fails the test.
pub fn status_is(code: i32, expected: i32, output: &str, what: &str) -> bool {
    if code == expected {
        return true;
    }
    if code == 4 && LOAD_FAULTS.iter().any(|words| output.contains(words)) {
        println!("{what}: a loaded machine's fault, the verdict not checked:\n{output}");
        return false;
    }
    if code == 3 && expected != 3 && unsafe_only_by_relaxed_ticks(output) {
        println!(
            "{what}: unsafe only by relaxed ticks (the example robot's ±10 % [uncertainty] \
             against cables that only pull: issue 29), the verdict not checked:\n{output}"
        );
        return false;
    }
    panic!("{what}: exit {code}, expected {expected}:\n{output}");
}

/// Reads `dir/run.mcap` back with [`softcbf::mcap_log::read_mcap`] and checks that its
/// runs are the records of the CSVs beside it (`trajectory.csv` as `run`, and
/// `trajectory_pd.csv` as `pd` when there), value for value (a NaN as a NaN), and its
/// metadata summary.json (and hardware.json when there). Returns the log.
pub fn assert_log_is_the_csvs(dir: &Path, run: &str) -> softcbf::mcap_log::McapLog {
    use softcbf::record::Record;
    let log = softcbf::mcap_log::read_mcap(&dir.join("run.mcap"))
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    let mut expected = vec![(run, "trajectory.csv")];
    if dir.join("trajectory_pd.csv").exists() {
        expected.push(("pd", "trajectory_pd.csv"));
    }
    let names: Vec<&str> = log.runs.iter().map(|(name, _)| name.as_str()).collect();
    assert_eq!(
        names,
        expected.iter().map(|(name, _)| *name).collect::<Vec<_>>()
    );
    for (name, file) in expected {
        let csv = Record::read_csv(&dir.join(file)).unwrap();
        let read = log.run(name).unwrap();
        assert_eq!(read.columns(), csv.columns(), "{name}");
        assert_eq!(read.len(), csv.len(), "{name}");
        let same = |a: &f64, b: &f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        let differ = read
            .values()
            .iter()
            .zip(csv.values())
            .position(|(a, b)| !same(a, b));
        assert_eq!(
            differ, None,
            "{name}: the log's values differ from {file}'s"
        );
    }
    let json = |file: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.join(file)).unwrap()).unwrap()
    };
    assert_eq!(log.summary, Some(json("summary.json")));
    let hardware = dir
        .join("hardware.json")
        .exists()
        .then(|| json("hardware.json"));
    assert_eq!(log.hardware, hardware);
    log
}
