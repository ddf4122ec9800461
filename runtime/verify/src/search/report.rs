//! What `softcbf verify --search` writes and reads back: `search.csv` (every evaluated
//! run, with the island, generation and candidate it came from), `search-shard.json`
//! (which search and which islands a directory holds) and `report.json` (per group the
//! runs spent, how many were unsafe, when the first came and the worst case found, with
//! the command that replays it). The report is a function of the rows alone, written and
//! read through [`SearchReport`].

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::report::is_unsafe;
use crate::search::cem::Settings;
use crate::search::{Candidate, score};
use crate::table::{TableError, read, read_runs, runs_csv};

/// What identifies a search: shards of one search agree on all of it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SearchBatch {
    /// The scenario file as given on the command line.
    pub scenario: String,
    /// Fingerprint of the scenario and robot files.
    pub fingerprint: String,
    /// The search's seed.
    pub seed: u64,
    /// Its budget of runs (all groups and islands together).
    pub runs: usize,
    /// Independent searches the budget is split into.
    pub islands: usize,
    /// `--duration`, when the command line replaced the scenario's \[s\].
    pub duration: Option<f64>,
    /// A run whose lowest barrier falls below this is unsafe (m or rad).
    pub threshold: f64,
    /// The groups' names (safety mode @ rate), in order.
    pub groups: Vec<String>,
    /// Generalized coordinates of the robot.
    pub coordinates: usize,
    /// The method's settings.
    pub method: Settings,
    /// The variables searched, in order.
    pub variables: Vec<String>,
}

/// `search-shard.json`: the search and the islands a directory holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SearchManifest {
    /// The search.
    pub search: SearchBatch,
    /// The islands held: `first..end`.
    pub first: usize,
    pub end: usize,
    /// The softcbf version that wrote it.
    pub software: String,
}

/// The worst case a group's search found.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WorstCase {
    /// Where it came from: island, generation, place in the generation, and the run's
    /// index in its island's search of the group.
    pub island: usize,
    pub generation: usize,
    pub candidate: usize,
    pub run: usize,
    /// Its lowest barrier (m, or rad for a bend limit); `null`: the state left the model's
    /// domain or the run stopped early (`-∞` in `search.csv`).
    pub lowest_barrier: Option<f64>,
    /// Which barrier, and when \[s\].
    pub barrier: String,
    pub t: f64,
    /// Ticks with a state outside the model's domain; why the run stopped early (empty if
    /// it did not).
    pub invalid_state: usize,
    pub stopped: String,
    /// Whether it is unsafe (below the threshold, outside the domain, or stopped).
    pub unsafe_run: bool,
    /// What the run was given: set point \[m\], initial `q` \[m\] and `q̇` \[m/s\], the
    /// plant's factors per module (bend and axial stiffness, bend and axial damping,
    /// mass), the noise seed.
    pub set_point: Vec<f64>,
    pub initial_q: Vec<f64>,
    pub initial_qd: Vec<f64>,
    pub factors: Vec<[f64; 5]>,
    pub noise_seed: u64,
    /// The scenario file that runs it again (in the output directory).
    pub scenario_file: String,
    /// The command that runs it again, with the figures of `softcbf simulate`.
    pub replay: String,
}

/// What the search of one group found.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroupSearch {
    /// `sampled @ 33.3 Hz`.
    pub name: String,
    /// Runs spent on it.
    pub runs: usize,
    /// Unsafe runs among them.
    pub unsafe_runs: usize,
    /// Runs spent up to and including the first unsafe one (counted generation by
    /// generation, islands side by side, as the figure draws them); `null`: none.
    pub first_unsafe: Option<usize>,
    /// The worst run (`null` without runs).
    pub worst: Option<WorstCase>,
}

/// `report.json` of a search.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SearchReport {
    /// The search.
    pub search: SearchBatch,
    /// Runs evaluated, and unsafe among them.
    pub evaluated: usize,
    pub unsafe_runs: usize,
    /// Each group.
    pub groups: Vec<GroupSearch>,
}

/// The name of a group as a file-name part: `paper @ 1000 Hz` → `paper-1000hz`.
pub fn slug(name: &str) -> String {
    let mut out = String::new();
    for c in name.chars() {
        if c.is_ascii_alphanumeric() || c == '.' {
            out.push(c.to_ascii_lowercase());
        } else if !out.ends_with('-') && !out.is_empty() {
            out.push('-');
        }
    }
    let out = out.trim_end_matches('-').replace("-hz", "hz");
    if out.is_empty() { "group".into() } else { out }
}

/// The worst-case scenario file of group `name`.
pub fn worst_file(name: &str) -> String {
    format!("worst-{}.toml", slug(name))
}

/// The command that replays the worst case of group `name` written into `out`.
pub fn replay_command(out: &Path, name: &str) -> String {
    let word = |p: &Path| softcbf_description::toml_file::shell_word(p);
    format!(
        "softcbf simulate --scenario {} --out {}",
        word(&out.join(worst_file(name))),
        word(&out.join(format!("replay-{}", slug(name))))
    )
}

/// The candidates of group `g` in the order runs are counted: generation by generation,
/// islands side by side, each generation in the order drawn.
pub fn in_spending_order(candidates: &[Candidate], g: usize) -> Vec<&Candidate> {
    let mut members: Vec<&Candidate> = candidates
        .iter()
        .filter(|c| c.row.draw.group == g)
        .collect();
    members.sort_by_key(|c| (c.generation, c.island, c.candidate));
    members
}

/// The report of `candidates` (every run of `search`); replay commands name `out`.
pub fn report(search: &SearchBatch, candidates: &[Candidate], out: &Path) -> SearchReport {
    let threshold = search.threshold;
    let groups = search
        .groups
        .iter()
        .enumerate()
        .map(|(g, name)| {
            let members = in_spending_order(candidates, g);
            let first_unsafe = members
                .iter()
                .position(|c| is_unsafe(&c.row, threshold))
                .map(|k| k + 1);
            // Lowest score; ties go to the first in island, run order.
            let worst = members
                .iter()
                .copied()
                .min_by(|a, b| {
                    score(&a.row)
                        .total_cmp(&score(&b.row))
                        .then((a.island, a.row.run).cmp(&(b.island, b.row.run)))
                })
                .map(|c| {
                    let r = &c.row;
                    let d = &r.draw;
                    let lowest = score(r);
                    WorstCase {
                        island: c.island,
                        generation: c.generation,
                        candidate: c.candidate,
                        run: r.run,
                        lowest_barrier: lowest.is_finite().then_some(lowest),
                        barrier: r.lowest_label.clone(),
                        t: r.lowest_t,
                        invalid_state: r.counts.invalid_state,
                        stopped: r.stopped.clone(),
                        unsafe_run: is_unsafe(r, threshold),
                        set_point: d.set_point.clone(),
                        initial_q: d.initial_q.clone(),
                        initial_qd: d.initial_qd.clone(),
                        factors: d
                            .factors
                            .iter()
                            .map(|f| {
                                [
                                    f.stiffness[0],
                                    f.stiffness[1],
                                    f.damping[0],
                                    f.damping[1],
                                    f.mass,
                                ]
                            })
                            .collect(),
                        noise_seed: d.noise_seed,
                        scenario_file: worst_file(name),
                        replay: replay_command(out, name),
                    }
                });
            GroupSearch {
                name: name.clone(),
                runs: members.len(),
                unsafe_runs: members
                    .iter()
                    .filter(|c| is_unsafe(&c.row, threshold))
                    .count(),
                first_unsafe,
                worst,
            }
        })
        .collect::<Vec<_>>();
    SearchReport {
        search: search.clone(),
        evaluated: candidates.len(),
        unsafe_runs: groups.iter().map(|g| g.unsafe_runs).sum(),
        groups,
    }
}

/// `report.json`'s text (pretty, ending in a line end).
pub fn report_json(report: &SearchReport) -> String {
    let mut text = serde_json::to_string_pretty(report).unwrap_or_default();
    text.push('\n');
    text
}

/// Reads `report.json` written by [`report_json`].
pub fn read_report(path: &Path) -> Result<SearchReport, TableError> {
    let text = read(path)?;
    serde_json::from_str(&text).map_err(|e| TableError::Format {
        path: path.to_path_buf(),
        line: e.line(),
        message: format!("not the report.json of `softcbf verify --search`: {e}"),
    })
}

/// The columns `search.csv` puts before those of `runs.csv`.
const PREFIX: [&str; 3] = ["island", "generation", "candidate"];

/// `search.csv` of `candidates` (in the order given) for `coordinates` coordinates: the
/// island, generation and candidate, then the columns of `runs.csv` (`run` counting the
/// runs of one island's search of one group).
pub fn search_csv(candidates: &[Candidate], coordinates: usize) -> String {
    let rows: Vec<_> = candidates.iter().map(|c| c.row.clone()).collect();
    let runs = runs_csv(&rows, coordinates);
    let mut lines = runs.lines();
    let mut text = format!("{},{}\n", PREFIX.join(","), lines.next().unwrap_or(""));
    for (c, line) in candidates.iter().zip(lines) {
        text.push_str(&format!(
            "{},{},{},{line}\n",
            c.island, c.generation, c.candidate
        ));
    }
    text
}

/// Reads `search.csv` text written by [`search_csv`] (`path` names it in errors).
pub fn read_search(
    text: &str,
    path: &Path,
    coordinates: usize,
    groups: &[String],
) -> Result<Vec<Candidate>, TableError> {
    let format = |line: usize, message: String| TableError::Format {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut prefixes = Vec::new();
    let mut runs = String::new();
    for (k, line) in text.lines().enumerate() {
        let mut fields = line.splitn(PREFIX.len() + 1, ',');
        let head: Vec<&str> = fields.by_ref().take(PREFIX.len()).collect();
        let rest = fields.next().unwrap_or("");
        if k == 0 {
            if head != PREFIX {
                return Err(format(
                    1,
                    "the header is not that of `softcbf verify --search`'s search.csv".into(),
                ));
            }
        } else {
            if head.len() != PREFIX.len() {
                return Err(format(k + 1, "has too few fields".into()));
            }
            let mut numbers = [0usize; 3];
            for (n, (field, name)) in numbers.iter_mut().zip(head.iter().zip(PREFIX)) {
                *n = field.parse().map_err(|_| {
                    format(k + 1, format!("`{name}` is not a whole number: `{field}`"))
                })?;
            }
            prefixes.push(numbers);
        }
        runs.push_str(rest);
        runs.push('\n');
    }
    let rows = read_runs(&runs, path, coordinates, groups)?;
    Ok(prefixes
        .into_iter()
        .zip(rows)
        .map(|([island, generation, candidate], row)| Candidate {
            island,
            generation,
            candidate,
            row,
        })
        .collect())
}

/// Reads the shard directories `dirs` of one search and returns the search and every
/// candidate, island by island, after checking that they belong to one search and hold
/// each of its islands once. Returns too, per island, the directory that holds it.
pub fn merge(dirs: &[PathBuf]) -> Result<(SearchBatch, Vec<Candidate>, Vec<PathBuf>), TableError> {
    let mut search: Option<(SearchBatch, PathBuf)> = None;
    let mut parts: Vec<(usize, usize, PathBuf, Vec<Candidate>)> = Vec::new();
    for dir in dirs {
        let path = dir.join("search-shard.json");
        let text = read(&path)?;
        let manifest: SearchManifest =
            serde_json::from_str(&text).map_err(|e| TableError::Format {
                path: path.clone(),
                line: e.line(),
                message: format!("not a shard manifest of `softcbf verify --search`: {e}"),
            })?;
        match &search {
            None => search = Some((manifest.search.clone(), path.clone())),
            Some((first, first_path)) if *first != manifest.search => {
                return Err(TableError::Merge(format!(
                    "{} and {} belong to different searches (scenario, robot, seed, budget, \
                     islands or settings differ): merge only shards of one `softcbf verify \
                     --search` command",
                    first_path.display(),
                    path.display(),
                )));
            }
            Some(_) => {}
        }
        let csv = dir.join("search.csv");
        let s = &manifest.search;
        let rows = read_search(&read(&csv)?, &csv, s.coordinates, &s.groups)?;
        if rows
            .iter()
            .any(|c| !(manifest.first..manifest.end).contains(&c.island))
        {
            return Err(TableError::Merge(format!(
                "{} holds runs of islands outside {}..{} (search-shard.json)",
                csv.display(),
                manifest.first,
                manifest.end
            )));
        }
        parts.push((manifest.first, manifest.end, dir.clone(), rows));
    }
    let Some((search, _)) = search else {
        return Err(TableError::Merge("no shard directories given".into()));
    };
    parts.sort_by_key(|p| p.0);
    let mut next = 0;
    let mut holders = Vec::new();
    let mut candidates = Vec::new();
    for (first, end, dir, rows) in parts {
        if first < next {
            return Err(TableError::Merge(format!(
                "island {first} is in two shards: give each shard once"
            )));
        }
        if first > next {
            return Err(TableError::Merge(format!(
                "islands {next}..{first} of the search's {} are in none of the shards given",
                search.islands
            )));
        }
        holders.extend(std::iter::repeat_n(dir, end - first));
        candidates.extend(rows);
        next = end;
    }
    if next < search.islands {
        return Err(TableError::Merge(format!(
            "islands {next}..{} of the search's {} are in none of the shards given",
            search.islands, search.islands
        )));
    }
    let groups = search.groups.len();
    for (island, holder) in holders.iter().enumerate() {
        for group in 0..groups {
            let expected = super::budget(search.runs, groups, group, search.islands, island);
            let held = candidates
                .iter()
                .filter(|c| c.island == island && c.row.draw.group == group)
                .count();
            if held != expected {
                return Err(TableError::Merge(format!(
                    "{}: island {island} holds {held} runs of `{}`, its search spends \
                     {expected}: the shard did not finish; run it again",
                    holder.display(),
                    search.groups[group]
                )));
            }
        }
    }
    Ok((search, candidates, holders))
}

#[cfg(test)]
mod tests {
    use softcbf_description::uncertainty::ModuleFactors;

    use super::*;
    use crate::RunRow;
    use crate::control::SafetyMode;
    use crate::draw::Draw;
    use crate::sim::TickCounts;

    fn candidate(
        island: usize,
        generation: usize,
        k: usize,
        group: usize,
        lowest: f64,
    ) -> Candidate {
        Candidate {
            island,
            generation,
            candidate: k,
            row: RunRow {
                run: 3 * generation + k,
                draw: Draw {
                    seed: 9,
                    group,
                    safety: SafetyMode::Paper,
                    control_period: 0.0303,
                    set_point: vec![0.1 / 3.0, -1e-300, 0.0, 2.5e-7, -0.07, 1.0 / 7.0],
                    initial_q: vec![0.0; 6],
                    initial_qd: vec![0.0; 6],
                    factors: vec![
                        ModuleFactors {
                            stiffness: [0.8 + f64::EPSILON, 1.2],
                            damping: [1.0 / 3.0, 0.9],
                            mass: 1.1,
                        },
                        ModuleFactors::NOMINAL,
                    ],
                    noise_seed: (1 << 62) + 12345,
                },
                set_point_barrier: -0.0123,
                lowest_barrier: lowest,
                lowest_label: "module 1 corner 3".into(),
                lowest_t: 0.1 + 0.2,
                set_point_error: 1e-9,
                max_abs_tau: 500.4,
                counts: TickCounts {
                    ticks: 100,
                    invalid_state: usize::from(lowest == f64::NEG_INFINITY),
                    ..TickCounts::default()
                },
                integrator_steps: 300,
                stopped: String::new(),
            },
        }
    }

    fn batch() -> SearchBatch {
        SearchBatch {
            scenario: "s.toml".into(),
            fingerprint: "0123".into(),
            seed: 1,
            runs: 6,
            islands: 2,
            duration: None,
            threshold: -1e-6,
            groups: vec!["paper @ 33.0 Hz".into(), "other @ 33.0 Hz".into()],
            coordinates: 6,
            method: Settings::with_population(3),
            variables: vec!["set_point dx1 [m]".into()],
        }
    }

    #[test]
    fn report_and_rows_read_back_exactly() {
        let candidates = vec![
            candidate(0, 0, 0, 0, 2.0 / 3.0 * 1e-3),
            candidate(0, 0, 1, 0, -7.0 / 3.0 * 1e-6),
            candidate(0, 1, 0, 0, 1e-3),
            candidate(1, 0, 0, 0, f64::NEG_INFINITY),
            candidate(1, 0, 1, 0, -1e-3),
            candidate(1, 1, 0, 0, 0.5),
        ];
        let search = batch();
        let dir =
            std::env::temp_dir().join(format!("softcbf-search-report-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let report = report(&search, &candidates, &dir);
        let path = dir.join("report.json");
        std::fs::write(&path, report_json(&report)).unwrap();
        assert_eq!(read_report(&path).unwrap(), report);
        // Worst: island 1's run that left the domain; the first unsafe is the second run
        // spent (generation 0 of island 0, candidate 1).
        let group = &report.groups[0];
        let worst = group.worst.as_ref().unwrap();
        assert_eq!((worst.island, worst.lowest_barrier), (1, None));
        assert_eq!(group.first_unsafe, Some(2));
        assert_eq!((group.runs, group.unsafe_runs), (6, 3));
        assert_eq!(report.groups[1].worst, None);
        // search.csv reads back to the very candidates.
        let text = search_csv(&candidates, 6);
        let back = read_search(&text, Path::new("search.csv"), 6, &search.groups).unwrap();
        assert_eq!(back, candidates);
        assert_eq!(search_csv(&back, 6), text);
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(slug("sampled @ 33.0 Hz"), "sampled-33.0hz");
        assert_eq!(slug("hold-correction @ 1000 Hz"), "hold-correction-1000hz");
    }
}
