//! Sharding a study (issue 43, deliverable 5): the shards of a study, written to `study.json` and read back, merge
//! into the study run whole, byte for byte — its `study.json`, `summary.json`, printed table and Markdown table —
//! but for the wall-clock time and thread count; and a merge of parts that are not the shards of one study is a
//! named error.

use servostack::scenario::Scenario;
use servostack::study::{standard_families, Family, Shard, ShardError, Study, StudyResult};
use std::path::Path;

fn scenario() -> Scenario {
    let path = format!(
        "{}/assets/scenarios/ur5e_limits.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    Scenario::from_file(Path::new(&path)).unwrap()
}

fn families() -> Vec<Family> {
    standard_families()
        .into_iter()
        .filter(|f| ["mild", "goal_2cm"].contains(&f.name.as_str()))
        .collect()
}

/// The shard's result as the example writes it and a merge reads it: through `study.json`.
fn through_file(result: &StudyResult) -> StudyResult {
    StudyResult::from_json(&serde_json::to_string(result).unwrap(), "shard").unwrap()
}

/// Everything but the last line (the wall-clock time and thread count).
fn table(result: &StudyResult) -> String {
    let text = result.to_string();
    let lines: Vec<&str> = text.lines().collect();
    lines[..lines.len() - 1].join("\n")
}

#[test]
fn merged_shards_equal_the_study_run_whole_byte_for_byte() {
    let scenario = scenario();
    let study = Study::new(&scenario, families(), 5, 3).unwrap();
    let whole = study.run().unwrap();
    // Three shards of five draws: 0 and 3, 1 and 4, 2 — given in another order than their indices.
    let shards: Vec<StudyResult> = [2, 0, 1]
        .into_iter()
        .map(|i| {
            let shard = Shard::new(i, 3).unwrap();
            let result = study.clone().with_shard(shard).run().unwrap();
            for family in &result.families {
                assert!(family.draws.iter().all(|d| d.draw % 3 == i));
            }
            through_file(&result)
        })
        .collect();
    assert_ne!(shards[0].families[0].draws.len(), 5);
    let mut merged = StudyResult::merge(&shards).unwrap();
    assert_eq!(merged.shard, None);
    assert_eq!(merged.iterations, whole.iterations);
    assert_eq!(table(&merged), table(&whole));
    assert_eq!(merged.markdown_table(), whole.markdown_table());
    // The machines' fields: the merge sums the shards' (module docs); the rest must be identical bytes.
    assert_eq!(
        merged.threads,
        shards.iter().map(|s| s.threads).sum::<usize>()
    );
    merged.seconds = whole.seconds;
    merged.threads = whole.threads;
    assert_eq!(
        serde_json::to_string(&merged).unwrap(),
        serde_json::to_string(&whole).unwrap()
    );
    assert_eq!(
        serde_json::to_string_pretty(&merged.summary_json()).unwrap(),
        serde_json::to_string_pretty(&whole.summary_json()).unwrap()
    );
    // A study read back from its own file is itself.
    assert_eq!(through_file(&whole), whole);
}

#[test]
fn parts_that_are_not_the_shards_of_one_study_do_not_merge() {
    let scenario = scenario();
    let study = Study::new(&scenario, families()[..1].to_vec(), 2, 3).unwrap();
    let shard = |i, n, study: &Study<'_>| {
        study
            .clone()
            .with_shard(Shard::new(i, n).unwrap())
            .run()
            .unwrap()
    };
    let (first, second) = (shard(0, 2, &study), shard(1, 2, &study));
    let reason = |parts: &[StudyResult]| match StudyResult::merge(parts) {
        Err(ShardError::Mismatch { reason }) => reason,
        other => panic!("expected a mismatch, got {other:?}"),
    };
    assert!(reason(&[]).contains("no study"));
    assert!(reason(std::slice::from_ref(&first)).contains("shard 1/2 is missing"));
    assert!(reason(&[first.clone(), first.clone()]).contains("given twice"));
    let other_seed = Study::new(&scenario, families()[..1].to_vec(), 2, 4).unwrap();
    assert!(reason(&[first.clone(), shard(1, 2, &other_seed)]).contains("is not of the study"));
    assert!(
        reason(&[first.clone(), second.clone(), shard(2, 3, &study)])
            .contains("not one of 2 shards")
    );
    let whole = study.run().unwrap();
    assert!(reason(&[whole]).contains("is not a shard"));
    assert!(StudyResult::merge(&[second, first]).is_ok());
}

#[test]
fn shards_are_written_i_slash_n_and_checked() {
    let shard: Shard = "2/5".parse().unwrap();
    assert_eq!((shard.index(), shard.count()), (2, 5));
    assert_eq!(shard.to_string(), "2/5");
    assert!(shard.contains(7) && !shard.contains(8));
    for bad in ["5/5", "1/0", "a/2", "3", "-1/2", ""] {
        assert!(
            matches!(bad.parse::<Shard>(), Err(ShardError::InvalidShard { .. })),
            "{bad}"
        );
    }
    // A file that is not a study is a named error, as is an outcome no run has.
    assert!(matches!(
        StudyResult::from_json("{}", "x.json"),
        Err(ShardError::File { .. })
    ));
    let scenario = scenario();
    let result = Study::new(&scenario, families()[..1].to_vec(), 1, 3)
        .unwrap()
        .run()
        .unwrap();
    let text = serde_json::to_string(&result).unwrap();
    assert!(StudyResult::from_json(&text, "study.json").is_ok());
    // A shard index beyond its count, as a hand-edited file could have it, is refused when read.
    let shard = Study::new(&scenario, families()[..1].to_vec(), 1, 3)
        .unwrap()
        .with_shard(Shard::new(0, 2).unwrap())
        .run()
        .unwrap();
    let text_of_shard = serde_json::to_string(&shard).unwrap();
    assert!(text_of_shard.contains("\"shard\":{\"index\":0,\"count\":2}"));
    let beyond = text_of_shard.replace("\"index\":0,\"count\":2", "\"index\":5,\"count\":2");
    assert!(matches!(
        StudyResult::from_json(&beyond, "study.json"),
        Err(ShardError::File { .. })
    ));
    let renamed = text.replacen("\"outcome\":\"", "\"outcome\":\"flying_", 1);
    match StudyResult::from_json(&renamed, "study.json") {
        Err(ShardError::File { reason, .. }) => {
            assert!(reason.contains("unknown outcome"), "{reason}")
        }
        other => panic!("expected a file error, got {other:?}"),
    }
}
