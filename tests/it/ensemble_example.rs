//! `examples/forced_sweep.rs`, a user's own model (a forced, damped Duffing oscillator over
//! forcing amplitudes) through the library: the same table on one thread and on two, and
//! from three job-array parts merged (byte for byte). Its MPI run is in
//! `tests/cli_ensemble_mpi.rs`.

#[path = "../../examples/forced_sweep.rs"]
#[allow(dead_code)]
mod forced_sweep;

use crate::common::TempDir;

fn run(args: &[&str]) -> String {
    let args: Vec<String> = args.iter().map(|a| a.to_string()).collect();
    forced_sweep::run(&args).unwrap_or_else(|e| panic!("{args:?}: {e}"))
}

#[test]
fn the_example_on_threads_and_in_parts_merged_writes_one_table() {
    let dir = TempDir::new("forced-sweep");
    std::fs::create_dir_all(&dir.0).unwrap();
    let at = |name: &str| dir.0.join(name).to_str().unwrap().to_string();
    let base = ["--members", "12", "--periods", "25"];
    let mut tables = Vec::new();
    for threads in [1, 2] {
        let out = at(&format!("t{threads}.csv"));
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let line = pool.install(|| run(&[&base[..], &[out.as_str()]].concat()));
        // The chaotic members (γ past the period doublings) cannot be verified to 1e-8 over
        // 25 periods: their rows say "unverified" and hold the best solution.
        assert!(line.contains("table of 12 members, 8 verified"), "{line}");
        tables.push(std::fs::read_to_string(&out).unwrap());
    }
    assert_eq!(tables[0], tables[1]);
    // The first line and the run's fingerprint, then the header row and the rows.
    assert!(tables[0].starts_with("# ecr ensemble table of 12 members: "));
    let rows: Vec<&str> = tables[0].lines().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(rows[0], "member,gamma,status,amplitude,q_end,p_end,message");
    assert_eq!(rows.len(), 13);
    let parts: Vec<String> = (1..=3).map(|k| at(&format!("part{k}.csv"))).collect();
    for (k, part) in parts.iter().enumerate() {
        let shard = format!("{}/3", k + 1);
        let line = run(&[&base[..], &["--shard", &shard, part.as_str()]].concat());
        assert!(
            line.contains(&format!("part {shard} of 4 members")),
            "{line}"
        );
    }
    let merged = at("merged.csv");
    let line = run(&["merge", &merged, &parts[1], &parts[2], &parts[0]]);
    assert!(line.contains("12 members from 3 parts"), "{line}");
    assert_eq!(std::fs::read_to_string(&merged).unwrap(), tables[0]);
}
