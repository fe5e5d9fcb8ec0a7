//! Hand-built reports through the page builders: the SVG and the pages parse as XML, nothing
//! refers outside the file, and what the charts must show is there.

use super::*;
use crate::analyze::{DimAcf, ProfileCheck};
use crate::audit::{EpisodeAudit, Flag, Histogram, RepairExample, Thresholds, Verdict};

fn episode(
    id: u64,
    mean: f64,
    min: f64,
    max: f64,
    verdict: Verdict,
    flags: Vec<Flag>,
) -> EpisodeAudit {
    EpisodeAudit {
        id,
        n_frames: 100,
        interval_mean: mean,
        interval_std: (max - min) / 4.0,
        interval_min: min,
        interval_max: max,
        flags,
        verdict,
        detail: if verdict == Verdict::Ok {
            String::new()
        } else {
            format!("episode {id} <needs> & repair")
        },
        repaired_frames: if verdict == Verdict::Exclude { 0 } else { 100 },
        findings: Vec::new(),
    }
}

pub(crate) fn sample_audit() -> AuditReport {
    let mut episodes = Vec::new();
    for i in 0..40u64 {
        let wobble = (i as f64 * 0.7).sin() * 0.001;
        episodes.push(episode(
            i,
            0.05 + wobble,
            0.048 + wobble,
            0.052 + wobble,
            Verdict::Ok,
            vec![],
        ));
    }
    episodes[7] = episode(7, 0.053, 0.049, 0.1, Verdict::Interpolate, vec![Flag::Gap]);
    episodes[19] = episode(19, 0.056, 0.03, 0.08, Verdict::Resample, vec![Flag::Jitter]);
    episodes[31] = episode(
        31,
        0.08,
        0.02,
        0.4,
        Verdict::Exclude,
        vec![Flag::Gap, Flag::Count],
    );
    let before_t: Vec<f64> = (0..40)
        .filter(|&i| i != 12 && i != 13)
        .map(|i| i as f64 * 0.05)
        .collect();
    let before: Vec<f64> = before_t.iter().map(|t| (t * 3.0).sin()).collect();
    let after_t: Vec<f64> = (0..40).map(|i| i as f64 * 0.05).collect();
    let after: Vec<f64> = after_t.iter().map(|t| (t * 3.0).sin()).collect();
    AuditReport {
        expected_interval: 0.05,
        source_fps: 20.0,
        timestamps: true,
        thresholds: Thresholds {
            jitter: 0.1,
            gap: 1.5,
            count: 0.05,
        },
        repaired_fraction: 2.0 / 40.0,
        excluded_fraction: 1.0 / 40.0,
        histogram: Histogram {
            edges: (0..=20).map(|i| 0.02 + i as f64 * 0.004).collect(),
            counts: vec![
                1, 0, 2, 0, 0, 30, 900, 2500, 880, 25, 0, 0, 0, 3, 0, 0, 0, 0, 0, 2,
            ],
        },
        warnings: vec!["3 of 40 episodes flagged".into()],
        examples: vec![RepairExample {
            episode: 7,
            verdict: Verdict::Interpolate,
            channel: "action".into(),
            dim: 0,
            before_t,
            before,
            after_t,
            after,
        }],
        video: Vec::new(),
        doctor: None,
        doctor_seconds: None,
        episodes,
    }
}

pub(crate) fn sample_analyze() -> AnalyzeReport {
    let dims: Vec<DimAcf> = (0..3)
        .map(|d| DimAcf {
            dim: d,
            acf: (0..=60)
                .map(|k| (-(k as f64) / (5.0 + 3.0 * d as f64)).exp())
                .collect(),
            constant_episodes: if d == 2 { vec![4] } else { vec![] },
        })
        .collect();
    let mean_acf: Vec<f64> = (0..=60)
        .map(|k| dims.iter().map(|d| d.acf[k]).sum::<f64>() / 3.0)
        .collect();
    let profile = |name: &str, chunk: u32, acf: f64, warning: Option<&str>| ProfileCheck {
        name: name.into(),
        fps: 10.0,
        rate_factor: 1.0,
        chunk,
        chunk_source_steps: chunk as usize,
        acf_at_chunk: Some(acf),
        suggested_chunk: Some(9),
        warning: warning.map(str::to_string),
    };
    AnalyzeReport {
        channel: "action".into(),
        source_fps: 10.0,
        episodes: 5,
        steps: 500,
        max_lag: 60,
        threshold: 0.3,
        suggested_k: Some(9),
        suggested_seconds: Some(0.9),
        mean_acf,
        episodes_at_lag: vec![5; 61],
        dims,
        redundant_above: 0.5,
        independent_below: 0.1,
        profiles: vec![
            profile("dp", 16, 0.12, None),
            profile("act", 40, 0.01, Some("long chunk: <nearly independent>")),
        ],
        warnings: vec!["action[2] is constant in 1 episode(s)".into()],
    }
}

fn assert_svg(svg: &str) {
    let doc = roxmltree::Document::parse(svg).unwrap_or_else(|e| panic!("{e}\n{svg}"));
    assert_eq!(doc.root_element().tag_name().name(), "svg");
    assert!(svg.contains("<text"), "charts carry text labels");
}

/// The page parses as XML, loads nothing from outside, and runs no script.
fn assert_self_contained(html: &str) {
    let body = html
        .strip_prefix("<!DOCTYPE html>\n")
        .expect("doctype first");
    roxmltree::Document::parse(body).unwrap_or_else(|e| panic!("{e}"));
    let lower = html.to_lowercase();
    for bad in [
        "<script", "<link", "<img", "<iframe", "src=", "href=", "url(", "@import",
    ] {
        assert!(!lower.contains(bad), "{bad} in the page");
    }
    let without_namespace = lower.replace("xmlns=\"http://www.w3.org/2000/svg\"", "");
    assert!(!without_namespace.contains("http:") && !without_namespace.contains("https:"));
}

#[test]
fn every_chart_is_well_formed_svg() {
    let audit = sample_audit();
    let analyze = sample_analyze();
    let charts = [
        plot::interval_histogram(&audit.histogram, audit.expected_interval),
        plot::episode_timing(&audit.episodes, audit.expected_interval),
        plot::repair_example(&audit.examples[0]),
        plot::acf_curves(&analyze),
    ];
    for svg in &charts {
        assert_svg(svg);
        assert!(!svg.contains("chart failed"), "{svg}");
    }
    assert!(charts[0].contains("expected 50.0 ms"));
    assert!(charts[1].contains("interpolate (1)") && charts[1].contains("exclude (1)"));
    assert!(charts[3].contains("suggested K = 9") && charts[3].contains("act K = 40"));
}

/// The numbers along the bottom of the per-episode chart: the `<text>` elements below the
/// plotting area whose content is a number.
fn episode_axis_labels(svg: &str) -> Vec<f64> {
    let doc = roxmltree::Document::parse(svg).unwrap();
    let texts: Vec<(f64, f64)> = doc
        .descendants()
        .filter(|n| n.has_tag_name("text"))
        .filter_map(|n| {
            let value = n.text()?.trim().parse::<f64>().ok()?;
            Some((n.attribute("y")?.parse::<f64>().ok()?, value))
        })
        .collect();
    let bottom = texts.iter().map(|t| t.0).fold(f64::MIN, f64::max);
    texts
        .iter()
        .filter(|t| t.0 == bottom)
        .map(|t| t.1)
        .collect()
}

#[test]
fn episode_axis_shows_whole_episode_positions() {
    for n in [1usize, 3, 12, 40, 1234] {
        let mut episodes = sample_audit().episodes;
        episodes.resize(n, episodes[0].clone());
        let labels = episode_axis_labels(&plot::episode_timing(&episodes, 0.05));
        assert!(!labels.is_empty() && labels.len() <= 10, "{n}: {labels:?}");
        assert_eq!(labels[0], 0.0, "{n}: {labels:?}");
        for v in &labels {
            assert!(
                v.fract() == 0.0 && *v >= 0.0 && *v < n as f64,
                "{n}: {labels:?}"
            );
        }
    }
}

#[test]
fn audit_page_is_self_contained_and_lists_flagged_episodes() {
    let html = audit_html(&sample_audit(), "Audit <of> test");
    assert_self_contained(&html);
    assert_eq!(
        html.matches("<svg").count(),
        3,
        "histogram, timing, one repair"
    );
    assert!(html.contains("episode 31 &lt;needs&gt; &amp; repair"));
    assert!(html.contains("<td>gap, count</td>"));
    assert_eq!(
        html,
        audit_html(&sample_audit(), "Audit <of> test"),
        "deterministic"
    );
}

#[test]
fn analyze_page_is_self_contained_and_names_the_suggested_k() {
    let html = analyze_html(&sample_analyze(), "Analyze");
    assert_self_contained(&html);
    assert_eq!(html.matches("<svg").count(), 1);
    assert!(html.contains("Suggested K: 9 steps at 10 Hz (0.90 s)"));
    assert!(html.contains("long chunk: &lt;nearly independent&gt;"));
}

#[test]
fn empty_reports_still_render() {
    let mut audit = sample_audit();
    audit.episodes.clear();
    audit.examples.clear();
    audit.histogram = Histogram {
        edges: vec![],
        counts: vec![],
    };
    assert_self_contained(&audit_html(&audit, "empty"));
    let mut analyze = sample_analyze();
    analyze.suggested_k = None;
    analyze.dims.iter_mut().for_each(|d| d.acf.truncate(1));
    analyze.mean_acf.truncate(1);
    assert_self_contained(&analyze_html(&analyze, "short"));
}

/// `CHUNKC_SAMPLE_REPORT=path cargo test --lib report::` writes the sample audit page there, for
/// looking at it in a browser (the audit itself computes real ones).
#[test]
fn write_sample_audit_page_on_request() {
    if let Some(path) = std::env::var_os("CHUNKC_SAMPLE_REPORT") {
        std::fs::write(
            path,
            audit_html(&sample_audit(), "chunkc audit (sample data)"),
        )
        .unwrap();
    }
}
