//! Barrier labels, written and read in one place: the short stable names that
//! [`barrier_list`](crate::barriers::barrier_list) gives every barrier and that CSV headers,
//! reports, figures and the 3-D view carry (1-based numbers):
//!
//! - `module K corner J` — a plate corner;
//! - `module K elongation min`, `module K elongation max`, `module K bend` — a module's limits;
//! - `obstacle O module K corner J|centre|point N|arc N` — a watched point of an obstacle.
//!
//! A new barrier kind changes [`limit`] or [`KindGroup`]'s words here and nowhere else;
//! [`kind_group`] reads every label back (a test below writes every kind and reads it).

use crate::barriers::{BarrierKind, KindGroup};

/// The label of corner `corner` of module `module` (both 0-based): `module 1 corner 3`.
pub fn corner(module: usize, corner: usize) -> String {
    format!("module {} corner {}", module + 1, corner + 1)
}

/// The words a module's limit of `kind` adds to `module K`, `None` for the kinds that are not
/// a module's limit: `elongation min`, `elongation max`, `bend`.
pub fn limit_words(kind: BarrierKind) -> Option<&'static str> {
    match kind {
        BarrierKind::ElongationMin => Some("elongation min"),
        BarrierKind::ElongationMax => Some("elongation max"),
        BarrierKind::Bend => Some("bend"),
        BarrierKind::PlateCorner | BarrierKind::HalfSpace | BarrierKind::Sphere => None,
    }
}

/// The label of module `module`'s (0-based) limit `words` ([`limit_words`]):
/// `module 2 elongation max`.
pub fn limit(module: usize, words: &str) -> String {
    format!("module {} {words}", module + 1)
}

/// The label of obstacle `obstacle`'s (0-based) watched point on module `module` (0-based),
/// named `point` (`corner 4`, `centre`, `point 1`, `arc 2`): `obstacle 1 module 2 corner 4`.
pub fn obstacle_point(obstacle: usize, module: usize, point: &str) -> String {
    format!("obstacle {} module {} {point}", obstacle + 1, module + 1)
}

/// The kind group and module (0-based) a label names; `None` for text that is not a label
/// [`barrier_list`](crate::barriers::barrier_list) writes.
pub fn kind_group(label: &str) -> Option<(KindGroup, usize)> {
    if let Some(rest) = label.strip_prefix("obstacle ") {
        let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
        let (module, _) = split_module(rest[digits..].trim_start())?;
        return (digits > 0).then_some((KindGroup::Obstacle, module - 1));
    }
    let (module, rest) = split_module(label)?;
    let group = match rest.split(' ').next()? {
        "corner" => KindGroup::PlateCorner,
        "elongation" => KindGroup::Elongation,
        "bend" => KindGroup::Bend,
        _ => return None,
    };
    Some((group, module - 1))
}

/// `(K, rest)` of a label `module K rest` (`K` ≥ 1, 1-based as written; `rest` may be empty).
pub fn split_module(label: &str) -> Option<(usize, &str)> {
    let after = label.strip_prefix("module ")?;
    let digits = after.bytes().take_while(u8::is_ascii_digit).count();
    let module: usize = after[..digits].parse().ok()?;
    let rest = &after[digits..];
    if !(rest.is_empty() || rest.starts_with(' ')) || module == 0 {
        return None;
    }
    Some((module, rest.trim_start()))
}

/// The label without its `module K` words (`obstacle 1 module 2 arc 1` → `obstacle 1 arc
/// 1`, `module 2 bend` → `bend`); the label itself if it has none.
pub fn without_module(label: &str) -> String {
    let words: Vec<&str> = label.split(' ').collect();
    let at = words.windows(2).position(|pair| {
        pair[0] == "module" && !pair[1].is_empty() && pair[1].bytes().all(|b| b.is_ascii_digit())
    });
    match at {
        Some(k) => [&words[..k], &words[k + 2..]].concat().join(" "),
        None => label.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Robot;
    use crate::barriers::barrier_list;

    #[test]
    fn every_label_written_reads_back_as_its_kind_and_module() {
        // Every kind at once: corners, the three limits, both obstacle shapes with corner,
        // centre, listed and arc points.
        let text = r#"
name = "labels"
[[module]]
[[module]]
[[module]]
[[obstacle]]
kind = "sphere"
center = [0.0, 0.0, 0.5]
radius = 0.05
watch = [
  { module = 3, points = ["corners", "centre"] },
  { module = 2, plate_points = [[0.01, 0.0, 0.0]], arc = [0.5] },
]
[[obstacle]]
kind = "half-space"
normal = [1.0, 0.0, 0.0]
offset = -0.5
watch = [{ module = 1, points = ["corner 2"], arc = [0.3, 0.7] }]
"#;
        let robot = Robot::parse(text, std::path::Path::new("labels.toml"))
            .expect("the test's robot reads");
        let list = barrier_list(&robot.structure());
        let mut groups = std::collections::BTreeSet::new();
        for spec in &list {
            assert_eq!(
                kind_group(&spec.label),
                Some((spec.kind.group(), spec.module)),
                "{}",
                spec.label
            );
            groups.insert(spec.kind.group());
        }
        assert_eq!(groups.len(), crate::barriers::KIND_GROUPS.len(), "{list:?}");
    }

    #[test]
    fn text_that_is_no_label_is_refused() {
        for text in [
            "module 0 corner 1",
            "module 1 twist",
            "obstacle module 1 arc 2",
            "corner 1",
            "#1",
            "module x corner 1",
            "module 1corner 1",
            "",
        ] {
            assert_eq!(kind_group(text), None, "{text}");
        }
        assert_eq!(
            kind_group("module 12 elongation min"),
            Some((KindGroup::Elongation, 11))
        );
        assert_eq!(
            kind_group("obstacle 10 module 1 arc 2"),
            Some((KindGroup::Obstacle, 0))
        );
    }

    #[test]
    fn the_module_words_come_off() {
        assert_eq!(without_module("module 2 corner 6"), "corner 6");
        assert_eq!(without_module("module 2 bend"), "bend");
        assert_eq!(
            without_module("obstacle 1 module 2 arc 1"),
            "obstacle 1 arc 1"
        );
        assert_eq!(without_module("b1"), "b1");
        assert_eq!(split_module("module 3"), Some((3, "")));
    }
}
