//! The `chunkc analyze` page: suggested K, the ACF chart, and each profile's K against it.

use super::page::Page;
use super::plot;
use crate::analyze::AnalyzeReport;

fn fixed(v: Option<f64>) -> String {
    v.map_or("–".into(), |v| format!("{v:.3}"))
}

// Long function: the page's HTML, top to bottom.
pub fn render(r: &AnalyzeReport, title: &str) -> String {
    let mut page = Page::new(
        title,
        &format!(
            "Channel `{}`: {} dimension(s), {} episodes, {} steps at {} Hz; lags 0 to {}.",
            r.channel,
            r.dims.len(),
            r.episodes,
            r.steps,
            r.source_fps,
            r.max_lag
        ),
    );
    match r.suggested_k {
        Some(k) => page.note(
            "ok",
            &format!(
                "Suggested K: {k} steps at {} Hz ({:.2} s), the first lag where the mean ACF is below {}.",
                r.source_fps,
                k as f64 / r.source_fps,
                r.threshold
            ),
        ),
        None => page.note(
            "warn",
            &format!("The mean ACF stays above {} at every lag analyzed: no K suggested.", r.threshold),
        ),
    }
    page.figure(
        &plot::acf_curves(r),
        &format!(
            "Sample autocorrelation per dimension, averaged over episodes, and the mean over dimensions. \
             Dashed red: the {} threshold; dotted: the suggested K; solid colored lines: each profile's K in source steps.",
            r.threshold
        ),
    );

    page.heading("Profiles");
    page.paragraph(&format!(
        "A profile's K is checked at lag K × (source steps per profile step). Above {} the chunk's \
         last actions still repeat its first (a shorter K carries the same information); below {} \
         the chunk predicts actions that are nearly independent of its start.",
        r.redundant_above, r.independent_below
    ));
    let rows: Vec<Vec<String>> = r
        .profiles
        .iter()
        .map(|p| {
            vec![
                p.name.clone(),
                p.fps.to_string(),
                p.chunk.to_string(),
                p.chunk_source_steps.to_string(),
                fixed(p.acf_at_chunk),
                p.suggested_chunk.map_or("–".into(), |k| k.to_string()),
                // The full sentence follows the table as a note.
                p.warning
                    .as_deref()
                    .map_or("ok", |w| w.split(':').next().unwrap_or(w))
                    .to_string(),
            ]
        })
        .collect();
    page.table(
        &[
            "profile",
            "fps",
            "K",
            "K in source steps",
            "ACF at K",
            "suggested K at its rate",
            "verdict",
        ],
        &rows,
    );
    for p in &r.profiles {
        if let Some(w) = &p.warning {
            page.note("warn", &format!("{}: {w}", p.name));
        }
    }

    page.heading("Dimensions");
    let lags = [1, 5, 10, 20, 50];
    let mut header = vec!["dimension".to_string()];
    header.extend(lags.iter().map(|k| format!("ACF at {k}")));
    header.push(format!("first lag < {}", r.threshold));
    header.push("constant in episodes".into());
    let rows: Vec<Vec<String>> = r
        .dims
        .iter()
        .map(|d| {
            let mut row = vec![format!("{}[{}]", r.channel, d.dim)];
            row.extend(lags.iter().map(|&k| fixed(d.acf.get(k).copied())));
            row.push(
                (1..d.acf.len())
                    .find(|&k| d.acf[k] < r.threshold)
                    .map_or("–".into(), |k| k.to_string()),
            );
            row.push(d.constant_episodes.len().to_string());
            row
        })
        .collect();
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    page.table(&header, &rows);
    for w in &r.warnings {
        page.note("warn", w);
    }

    page.heading("Method");
    page.paragraph(
        "For every episode and dimension, acf[k] = Σ_{t<n−k} (x_t − x̄)(x_{t+k} − x̄) / Σ_t (x_t − x̄)², \
         the numbers statsmodels.tsa.stattools.acf gives with its defaults. Each lag is averaged over the \
         episodes long enough to have it; a dimension that is constant within an episode has no ACF there \
         and is left out of that episode's contribution. The analysis runs on the raw source at its own \
         rate; the numbers are in analyze.json beside this page.",
    );
    page.finish()
}
