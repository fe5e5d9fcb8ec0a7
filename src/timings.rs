//! Wall time of each build phase, printed to stderr when `CHUNKC_TIMINGS` is set (a tool for
//! finding where a build spends its time; see the book's performance page).

use std::sync::Mutex;
use std::time::Instant;

static PHASES: Mutex<Vec<(&'static str, f64, f64, u64)>> = Mutex::new(Vec::new());

/// Peak resident memory of the process so far, in MiB (`VmHWM`; 0 where unknown).
fn peak_rss_mib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        })
        .map_or(0, |kb| kb / 1024)
}

/// CPU seconds (user + system) of the whole process so far, from `/proc/self/stat` (Linux; 0
/// elsewhere). Clock ticks are 10 ms, so short phases read coarsely.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the parenthesized command name; utime and stime are fields 14 and 15.
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| {
        fields
            .get(i)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (ticks(11) + ticks(12)) / 100.0
}

fn enabled() -> bool {
    std::env::var_os("CHUNKC_TIMINGS").is_some_and(|v| !v.is_empty() && v != "0")
}

/// Measures a phase from now until the guard is dropped.
pub struct Phase {
    name: &'static str,
    start: Instant,
    cpu: f64,
}

pub fn phase(name: &'static str) -> Phase {
    Phase {
        name,
        start: Instant::now(),
        cpu: if enabled() { cpu_seconds() } else { 0.0 },
    }
}

impl Drop for Phase {
    fn drop(&mut self) {
        let seconds = self.start.elapsed().as_secs_f64();
        let (cpu, peak) = if enabled() {
            (cpu_seconds() - self.cpu, peak_rss_mib())
        } else {
            (0.0, 0)
        };
        if let Ok(mut phases) = PHASES.lock() {
            phases.push((self.name, seconds, cpu, peak));
        }
    }
}

/// Prints the phases measured so far (in the order they ended) and forgets them.
pub fn report() {
    let Ok(mut phases) = PHASES.lock() else {
        return;
    };
    if enabled() {
        for (name, seconds, cpu, peak) in phases.iter() {
            eprintln!(
                "timing: {name:<20} {seconds:7.3} s wall {cpu:7.2} s cpu  peak RSS {peak:5} MiB"
            );
        }
    }
    phases.clear();
}
