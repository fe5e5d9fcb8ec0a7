//! The `chunkc audit` page: verdict counts, the interval histogram, per-episode timing, the
//! episodes that need attention, and before/after charts of repaired episodes.

use super::page::Page;
use super::plot::{self, verdict_name};
use crate::audit::{AuditReport, Flag, Verdict};

fn flag_name(f: Flag) -> &'static str {
    f.name()
}

fn ms(seconds: f64) -> String {
    format!("{:.2}", seconds * 1000.0)
}

// Long function: the page's HTML, top to bottom.
pub fn render(r: &AuditReport, title: &str) -> String {
    let n = r.episodes.len();
    let mut page = Page::new(
        title,
        &format!(
            "{n} episodes at {} Hz (expected interval {} ms); {}.",
            r.source_fps,
            ms(r.expected_interval),
            if r.timestamps {
                "intervals from the source's timestamps"
            } else {
                "the source stores no timestamps, so every interval is the declared one"
            }
        ),
    );

    let verdicts = [
        Verdict::Ok,
        Verdict::Interpolate,
        Verdict::Resample,
        Verdict::Exclude,
    ];
    let rows: Vec<Vec<String>> = verdicts
        .iter()
        .map(|&v| {
            let count = r.episodes.iter().filter(|e| e.verdict == v).count();
            vec![verdict_name(v).to_string(), count.to_string()]
        })
        .collect();
    page.table(&["verdict", "episodes"], &rows);
    page.paragraph(&format!(
        "Repaired: {:.1} % of episodes; excluded: {:.1} %. Thresholds: jitter when the interval std \
         exceeds {} of the mean, gap when an interval exceeds {} expected intervals, count when the \
         frame count deviates from duration × rate by more than {}.",
        r.repaired_fraction * 100.0,
        r.excluded_fraction * 100.0,
        r.thresholds.jitter,
        r.thresholds.gap,
        r.thresholds.count
    ));
    for w in &r.warnings {
        page.note("warn", w);
    }

    page.heading("Intervals");
    page.figure(
        &plot::interval_histogram(&r.histogram, r.expected_interval),
        "Every inter-frame interval of every episode, binned; the dashed line is 1 / fps.",
    );
    page.figure(
        &plot::episode_timing(&r.episodes, r.expected_interval),
        "One column per episode in source order, colored by verdict.",
    );

    page.heading("Episodes that need attention");
    let flagged: Vec<Vec<String>> = r
        .episodes
        .iter()
        .filter(|e| e.verdict != Verdict::Ok || !e.flags.is_empty())
        .map(|e| {
            vec![
                e.id.to_string(),
                e.n_frames.to_string(),
                ms(e.interval_mean),
                ms(e.interval_std),
                ms(e.interval_min),
                ms(e.interval_max),
                e.flags
                    .iter()
                    .map(|&f| flag_name(f))
                    .collect::<Vec<_>>()
                    .join(", "),
                verdict_name(e.verdict).to_string(),
                e.repaired_frames.to_string(),
                e.detail.clone(),
            ]
        })
        .collect();
    if flagged.is_empty() {
        page.note(
            "ok",
            "Every episode is on time: no flags, nothing to repair.",
        );
    } else {
        page.table(
            &[
                "episode",
                "frames",
                "mean (ms)",
                "std (ms)",
                "min (ms)",
                "max (ms)",
                "flags",
                "verdict",
                "frames after",
                "why",
            ],
            &flagged,
        );
    }

    if !r.video.is_empty() {
        page.heading("Camera videos");
        page.paragraph(
            "Each episode's camera video against its rows: frames in the episode's span of the \
             file, the smallest and largest interval between them, and the farthest any row is \
             from the frame it gets (LeRobot's rule: the frame nearest the row's time, which must \
             be closer than tolerance_s = 0.1 ms).",
        );
        let rows: Vec<Vec<String>> = r
            .video
            .iter()
            .map(|v| {
                let c = &v.check;
                vec![
                    v.episode.to_string(),
                    c.camera.clone(),
                    c.codec.clone(),
                    c.rows.to_string(),
                    c.frames.to_string(),
                    ms(c.interval_min),
                    ms(c.interval_max),
                    ms(c.worst_gap),
                    c.problem.clone().unwrap_or_else(|| "ok".into()),
                ]
            })
            .collect();
        page.table(
            &[
                "episode",
                "camera",
                "codec",
                "rows",
                "frames",
                "min (ms)",
                "max (ms)",
                "worst gap (ms)",
                "check",
            ],
            &rows,
        );
    }

    if let Some(d) = &r.doctor {
        doctor_section(&mut page, r, d);
    }

    if !r.examples.is_empty() {
        page.heading("Repairs, before and after");
        for ex in &r.examples {
            page.figure(
                &plot::repair_example(ex),
                &format!(
                    "Episode {}: recorded frames (grey circles) and the {} series the build uses.",
                    ex.episode,
                    verdict_name(ex.verdict)
                ),
            );
        }
    }
    page.finish()
}

/// The dataset doctor's section: what it checked, its charts, and every finding with its reason.
fn doctor_section(page: &mut Page, r: &AuditReport, d: &crate::audit::doctor::DoctorSummary) {
    page.heading("Dataset doctor");
    let counts: Vec<String> = d.flagged.iter().map(|(k, v)| format!("{k}: {v}")).collect();
    page.paragraph(&format!(
        "Checks of `{}`{}: frozen, clipped, jump, duplicate, misaligned, mixed_convention, units, \
         short per episode; constant dimensions and shift across the recording for the dataset. \
         Flagged: {}. Tracked dimensions (action tracks state): {:?}; lag mode: {}; convention: {}.",
        d.action_channel,
        d.state_channel.as_ref().map(|s| format!(" against `{s}`")).unwrap_or_default(),
        if counts.is_empty() { "nothing".into() } else { counts.join(", ") },
        d.tracked_dims,
        d.lag_mode.map_or("none (no dimension tracks the state)".into(), |m| m.to_string()),
        d.convention.as_deref().unwrap_or("unclear"),
    ));
    if !d.lag_curve.is_empty() {
        page.figure(&super::doctor_plot::lag_chart(d), "Per episode, the lag at which the action best predicts the next state change; flagged `misaligned` when it is more than `lag_tolerance` from the mode.");
    }
    page.figure(&super::doctor_plot::units_chart(d, d.units_ratio), "Per episode, the action's units against the dataset's (the gain of the state's response, or the action's spread where nothing tracks the state); outside the dashed lines: `units`.");
    if !d.shift.is_empty() {
        page.figure(&super::doctor_plot::shift_chart(d, d.shift_threshold), "Per dimension, each quarter of the recording's median episode mean, in robust standard deviations of the episode means.");
    }
    let rows: Vec<Vec<String>> = r
        .episodes
        .iter()
        .flat_map(|e| {
            e.findings.iter().map(move |f| {
                let evidence: Vec<String> = f
                    .evidence
                    .iter()
                    .map(|(k, v)| format!("{k} = {v:.4}"))
                    .collect();
                vec![
                    e.id.to_string(),
                    f.flag.name().to_string(),
                    format!("{:?}", f.action).to_lowercase(),
                    f.detail.clone(),
                    evidence.join(", "),
                ]
            })
        })
        .collect();
    if rows.is_empty() {
        page.note("ok", "The doctor found nothing to flag.");
    } else {
        page.table(&["episode", "flag", "action", "why", "evidence"], &rows);
    }
}
