//! The exit statuses of the `softcbf` command: one meaning each, so a script (or a person)
//! can tell a safe run from an unsafe one, a fault, and a run that never started; and what
//! each means for each command, the table the docs show ([`table`]).

/// Done, and safe: every barrier stayed above the threshold and every tick was valid and
/// filtered, its barrier rows met (none relaxed).
pub const OK: u8 = 0;
/// Not done, or not all of it: a bad file, setting or port, a loop rate the bus cannot hold
/// (measured before torque on), a safe start that refused, a run that completed no tick, a
/// batch interrupted, an output (log, figure, standard output) that could not be written.
pub const ERROR: u8 = 1;
/// The command line could not be read (unknown option, missing value).
pub const USAGE: u8 = 2;
/// Done, but not safe: a barrier fell below the threshold, or ticks had an invalid state,
/// no verified command (the zero command was applied), no filter or relaxed barrier rows
/// (rows with no common point), or deadlines were
/// missed beyond the allowed fraction, or a model value was not finite.
pub const UNSAFE: u8 = 3;
/// A hardware run stopped on a fault: communication lost, a servo's hardware error, the
/// loop too slow or paused past the servos' watchdog, a torque-off not confirmed.
pub const FAULT: u8 = 4;

/// The more serious of two statuses (`FAULT > UNSAFE > ERROR > OK`; `USAGE` is only ever
/// returned alone).
pub fn worst(a: u8, b: u8) -> u8 {
    let rank = |code: u8| match code {
        FAULT => 4,
        UNSAFE => 3,
        ERROR | USAGE => 2,
        _ => 0,
    };
    if rank(b) > rank(a) { b } else { a }
}

/// The commands, in the columns of [`table`].
pub const COMMANDS: [&str; 4] = [
    "`simulate`, `verify replay`",
    "`verify` (a batch or a shard), `verify merge`",
    "`run`",
    "`model`, `plot`, `view`, `identify`, `emulate`",
];

/// What each status means for each command of [`COMMANDS`].
pub const MEANINGS: [(u8, [&str; 4]); 5] = [
    (
        OK,
        [
            "safe: every tick filtered with a verified command at a valid state, no barrier \
             row relaxed, every recorded barrier at or above `--barrier-threshold` (default −1e-6 m)",
            "every run safe (each judged as `simulate` judges it)",
            "safe as for `simulate`, at the states read (`--barrier-threshold` default −1 mm), \
             with at most `--max-overrun-fraction` (default 5 %) of the deadlines and of the \
             holds missed",
            "done (`model`: every value finite; `emulate`: stopped by a signal)",
        ],
    ),
    (
        ERROR,
        [
            "not done, or not all of it: a bad file, option or value; an output (a file, a \
             figure, standard output) not written",
            "as for `simulate`; a batch interrupted by a signal (its finished runs are \
             written; `--resume` continues it); shards that do not make one batch",
            "as for `simulate`; a rate the bus cannot hold, a reply timeout the adapter's \
             latency timer cannot meet, a safe start that refused (torque never on); no tick \
             completed",
            "as for `simulate`",
        ],
    ),
    (
        USAGE,
        [
            "the command line could not be read (an unknown option, a missing value)",
            "as for `simulate`",
            "as for `simulate`",
            "as for `simulate`",
        ],
    ),
    (
        UNSAFE,
        [
            "unsafe: a barrier below the threshold, a recorded row or a tick with an invalid \
             state, a failed QP (the zero command applied), ticks without the filter \
             (`--no-filter`), ticks whose barrier rows were relaxed (no common point), the \
             run stopped early",
            "a run of the batch or shard unsafe (the report counts them)",
            "unsafe as for `simulate`, or more deadlines or holds missed than \
             `--max-overrun-fraction` allows",
            "`model`: a value of the model not finite at the state",
        ],
    ),
    (
        FAULT,
        [
            "",
            "",
            "stopped on a fault: communication lost, a servo's hardware error, the loop too \
             slow (`--min-rate`) or paused past the servos' watchdog, a torque-off not \
             confirmed",
            "",
        ],
    ),
];

/// The Markdown table of [`MEANINGS`]: a row per status, a column per group of
/// [`COMMANDS`]; docs/hardware.md and docs/verify.md show it as it is.
pub fn table() -> String {
    let mut text = format!("| status | {} |\n", COMMANDS.join(" | "));
    text += &format!("|---|{}\n", "---|".repeat(COMMANDS.len()));
    for (status, meanings) in MEANINGS {
        let cells: Vec<&str> = meanings
            .iter()
            .map(|m| if m.is_empty() { "—" } else { m })
            .collect();
        text += &format!("| {status} | {} |\n", cells.join(" | "));
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_docs_show_the_table_of_the_statuses() {
        let table = table();
        for doc in ["docs/hardware.md", "docs/verify.md"] {
            let path = format!("{}/../../{doc}", env!("CARGO_MANIFEST_DIR"));
            let text = std::fs::read_to_string(&path).unwrap();
            assert!(
                text.contains(&table),
                "{doc} does not show the exit statuses as runtime/core/src/exit.rs has them; \
                 put this table in it:\n{table}"
            );
        }
    }

    #[test]
    fn the_most_serious_status_wins() {
        assert_eq!(worst(OK, UNSAFE), UNSAFE);
        assert_eq!(worst(FAULT, UNSAFE), FAULT);
        assert_eq!(worst(ERROR, UNSAFE), UNSAFE);
        assert_eq!(worst(ERROR, OK), ERROR);
    }
}
