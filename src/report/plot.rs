// Long file: the report's charts share one drawing style; each chart is one function.
//! The report's charts, drawn with `plotters` into SVG strings. Text is emitted as SVG `<text>`
//! with a generic `sans-serif` family, so no font files are read and the viewer picks the font.

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::analyze::AnalyzeReport;
use crate::audit::{EpisodeAudit, Histogram, RepairExample, Verdict};

pub(super) type Area<'a> = DrawingArea<SVGBackend<'a>, Shift>;
pub(super) type Fallible = Result<(), Box<dyn std::error::Error + 'static>>;

const WIDTH: u32 = 960;
const HEIGHT: u32 = 420;
pub(super) const FONT: &str = "sans-serif";

pub(super) const GREY: RGBColor = RGBColor(150, 150, 150);
pub(super) const THRESHOLD_RED: RGBColor = RGBColor(200, 50, 45);
/// Distinguishable colors for a handful of series (dimensions, profiles).
pub(super) const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 111, 180),
    RGBColor(230, 120, 20),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
    RGBColor(188, 189, 34),
];

/// The color a verdict has in every chart and table.
pub fn verdict_color(v: Verdict) -> RGBColor {
    match v {
        Verdict::Ok => RGBColor(46, 139, 62),
        Verdict::Interpolate => RGBColor(230, 149, 0),
        Verdict::Resample => RGBColor(31, 111, 180),
        Verdict::Exclude => RGBColor(200, 50, 45),
    }
}

pub fn verdict_name(v: Verdict) -> &'static str {
    match v {
        Verdict::Ok => "ok",
        Verdict::Interpolate => "interpolate",
        Verdict::Resample => "resample",
        Verdict::Exclude => "exclude",
    }
}

/// Draws into a fresh SVG; a drawing error becomes a chart that says so (a report with one
/// broken chart is still worth more than no report).
pub(super) fn svg(draw: impl FnOnce(&Area) -> Fallible) -> String {
    let mut out = String::new();
    let result = {
        let root = SVGBackend::with_string(&mut out, (WIDTH, HEIGHT)).into_drawing_area();
        draw(&root).and_then(|()| root.present().map_err(Into::into))
    };
    match result {
        Ok(()) => out,
        Err(e) => {
            let mut fallback = String::new();
            let root = SVGBackend::with_string(&mut fallback, (WIDTH, 60)).into_drawing_area();
            let text = format!("chart failed: {e}");
            let _ = root.draw_text(
                &text,
                &(FONT, 16).into_font().color(&THRESHOLD_RED),
                (10, 20),
            );
            let _ = root.present();
            drop(root);
            fallback
        }
    }
}

/// Axis numbers without trailing zeros (`20`, `0.2`, never `-0.0`).
pub(super) fn tick(v: &f64) -> String {
    let rounded = (v * 1e6).round() / 1e6;
    if rounded == 0.0 {
        "0".into()
    } else {
        format!("{rounded}")
    }
}

/// An axis of `n` items (episodes) drawn at 0..n, spanning -0.5..n-0.5: its ticks are whole
/// numbers 0, step, 2·step, … with a step of 1, 2 or 5 × 10^k (an episode axis never shows 1.5),
/// and it has no light grid lines between them.
struct EpisodeAxis {
    inner: plotters::coord::types::RangedCoordf64,
    n: usize,
}

impl Ranged for EpisodeAxis {
    type FormatOption = plotters::coord::ranged1d::DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.inner.map(value, limit)
    }

    fn key_points<Hint: plotters::coord::ranged1d::KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if matches!(
            hint.weight(),
            plotters::coord::ranged1d::KeyPointWeight::Any
        ) || hint.max_num_points() == 0
        {
            return Vec::new();
        }
        let most = hint.max_num_points().clamp(1, 10);
        let mut step = 1usize;
        'find: loop {
            for m in [1, 2, 5] {
                if self.n.div_ceil(step * m) <= most {
                    step *= m;
                    break 'find;
                }
            }
            step *= 10;
        }
        (0..self.n.max(1)).step_by(step).map(|i| i as f64).collect()
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.inner.range()
    }
}

pub(super) const GRID: RGBColor = RGBColor(238, 238, 238);

/// `lo..hi`, widened when empty so that plotters gets a usable range.
pub(super) fn span(lo: f64, hi: f64) -> std::ops::Range<f64> {
    if !(lo.is_finite() && hi.is_finite()) {
        return 0.0..1.0;
    }
    if hi - lo > 1e-12 * hi.abs().max(1.0) {
        lo..hi
    } else {
        let pad = (lo.abs() * 0.1).max(1e-3);
        lo - pad..hi + pad
    }
}

pub(super) fn legend_line(
    color: RGBColor,
    width: u32,
) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(width))
}

pub(super) fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(GREY)
        .label_font((FONT, 13))
        .draw()
}

/// All inter-frame intervals, binned, in milliseconds; the expected interval as a dashed line.
pub fn interval_histogram(h: &Histogram, expected: f64) -> String {
    svg(|root| {
        root.fill(&WHITE)?;
        let ms = |s: f64| s * 1000.0;
        let lo = h.edges.first().copied().unwrap_or(expected).min(expected);
        let hi = h.edges.last().copied().unwrap_or(expected).max(expected);
        // Log scale: a handful of long gaps among thousands of regular intervals must show.
        let top = h.counts.iter().copied().max().unwrap_or(1).max(1) as f64 * 2.0;
        let floor = 0.7;
        let mut chart = ChartBuilder::on(root)
            .caption("Inter-frame intervals, all episodes", (FONT, 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(span(ms(lo), ms(hi)), (floor..top).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("interval (ms)")
            .y_desc("intervals (log scale)")
            .x_label_formatter(&tick)
            .y_label_formatter(&tick)
            .light_line_style(GRID)
            .label_style((FONT, 12))
            .axis_desc_style((FONT, 14))
            .draw()?;
        chart
            .draw_series(
                h.counts
                    .iter()
                    .enumerate()
                    .filter(|(_, &c)| c > 0)
                    .map(|(i, &c)| {
                        Rectangle::new(
                            [(ms(h.edges[i]), floor), (ms(h.edges[i + 1]), c as f64)],
                            PALETTE[0].mix(0.75).filled(),
                        )
                    }),
            )?
            .label("intervals per bin")
            .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], PALETTE[0].filled()));
        chart
            .draw_series(DashedLineSeries::new(
                [(ms(expected), floor), (ms(expected), top)],
                8,
                5,
                THRESHOLD_RED.stroke_width(2),
            ))?
            .label(format!("expected {:.1} ms", ms(expected)))
            .legend(legend_line(THRESHOLD_RED, 2));
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}

/// Per episode in source order: the mean interval (dot) and the min–max range (bar), colored by
/// verdict; the expected interval as a dashed line.
// Long function: one chart: axes, series and annotations in drawing order.
pub fn episode_timing(episodes: &[EpisodeAudit], expected: f64) -> String {
    svg(|root| {
        root.fill(&WHITE)?;
        let ms = |s: f64| s * 1000.0;
        let lo = episodes
            .iter()
            .map(|e| e.interval_min)
            .fold(expected, f64::min);
        let hi = episodes
            .iter()
            .map(|e| e.interval_max)
            .fold(expected, f64::max);
        let pad = (hi - lo).max(expected * 0.1) * 0.08;
        let n = episodes.len().max(1) as f64;
        let mut chart = ChartBuilder::on(root)
            .caption(
                "Interval per episode: mean (dot) and min–max (bar)",
                (FONT, 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(
                EpisodeAxis {
                    inner: (-0.5..n - 0.5).into(),
                    n: episodes.len(),
                },
                span(ms(lo - pad).max(0.0), ms(hi + pad)),
            )?;
        chart
            .configure_mesh()
            .x_desc("episode (position in source order)")
            .y_desc("interval (ms)")
            .x_label_formatter(&tick)
            .y_label_formatter(&tick)
            .light_line_style(GRID)
            .label_style((FONT, 12))
            .axis_desc_style((FONT, 14))
            .draw()?;
        for verdict in [
            Verdict::Ok,
            Verdict::Interpolate,
            Verdict::Resample,
            Verdict::Exclude,
        ] {
            let color = verdict_color(verdict);
            let of_verdict: Vec<(usize, &EpisodeAudit)> = episodes
                .iter()
                .enumerate()
                .filter(|(_, e)| e.verdict == verdict)
                .collect();
            if of_verdict.is_empty() {
                continue;
            }
            chart.draw_series(of_verdict.iter().map(|&(i, e)| {
                PathElement::new(
                    vec![
                        (i as f64, ms(e.interval_min)),
                        (i as f64, ms(e.interval_max)),
                    ],
                    color.mix(0.6).stroke_width(2),
                )
            }))?;
            chart
                .draw_series(of_verdict.iter().map(|&(i, e)| {
                    Circle::new((i as f64, ms(e.interval_mean)), 3, color.filled())
                }))?
                .label(format!("{} ({})", verdict_name(verdict), of_verdict.len()))
                .legend(move |(x, y)| Circle::new((x + 10, y), 4, color.filled()));
        }
        chart
            .draw_series(DashedLineSeries::new(
                [(-0.5, ms(expected)), (n - 0.5, ms(expected))],
                8,
                5,
                THRESHOLD_RED.stroke_width(1),
            ))?
            .label(format!("expected {:.1} ms", ms(expected)))
            .legend(legend_line(THRESHOLD_RED, 1));
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}

/// The ACF per dimension (thin) and their mean (thick), the threshold as a dashed line, the
/// suggested K and each profile's K (in source steps) as vertical lines.
// Long function: one chart: axes, series and annotations in drawing order.
pub fn acf_curves(r: &AnalyzeReport) -> String {
    svg(|root| {
        root.fill(&WHITE)?;
        let last = r.mean_acf.len().saturating_sub(1).max(1) as f64;
        let low = r
            .dims
            .iter()
            .flat_map(|d| d.acf.iter().copied())
            .fold(-0.1f64, f64::min);
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!("Autocorrelation of `{}` at {} Hz", r.channel, r.source_fps),
                (FONT, 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..last, (low - 0.05)..1.05)?;
        chart
            .configure_mesh()
            .x_desc("lag (source steps)")
            .y_desc("ACF")
            .x_label_formatter(&tick)
            .y_label_formatter(&tick)
            .light_line_style(GRID)
            .label_style((FONT, 12))
            .axis_desc_style((FONT, 14))
            .draw()?;
        let few = r.dims.len() <= PALETTE.len();
        for (i, d) in r.dims.iter().enumerate() {
            if d.acf.is_empty() {
                continue;
            }
            let color = if few {
                PALETTE[i].mix(0.7)
            } else {
                GREY.mix(0.5)
            };
            let series = chart.draw_series(LineSeries::new(
                d.acf.iter().enumerate().map(|(k, &v)| (k as f64, v)),
                color.stroke_width(1),
            ))?;
            if few {
                series
                    .label(format!("{}[{}]", r.channel, d.dim))
                    .legend(legend_line(PALETTE[i], 2));
            } else if i == 0 {
                series.label("each dimension").legend(legend_line(GREY, 1));
            }
        }
        chart
            .draw_series(LineSeries::new(
                r.mean_acf.iter().enumerate().map(|(k, &v)| (k as f64, v)),
                BLACK.stroke_width(3),
            ))?
            .label("mean over dimensions")
            .legend(legend_line(BLACK, 3));
        chart
            .draw_series(DashedLineSeries::new(
                [(0.0, r.threshold), (last, r.threshold)],
                8,
                5,
                THRESHOLD_RED.stroke_width(2),
            ))?
            .label(format!("threshold {}", r.threshold))
            .legend(legend_line(THRESHOLD_RED, 2));
        let label = |text: String, x: f64, row: usize, color: RGBColor| {
            Text::new(
                text,
                (x + last * 0.008, 1.0 - 0.07 * row as f64),
                (FONT, 13).into_font().color(&color),
            )
        };
        if let Some(k) = r.suggested_k {
            chart.draw_series(DashedLineSeries::new(
                [(k as f64, low - 0.05), (k as f64, 1.05)],
                3,
                3,
                BLACK.stroke_width(1),
            ))?;
            chart.draw_series([label(format!("suggested K = {k}"), k as f64, 0, BLACK)])?;
        }
        for (i, p) in r.profiles.iter().enumerate() {
            let k = p.chunk_source_steps as f64;
            if k > last {
                continue;
            }
            let color = PALETTE[(i + 1) % PALETTE.len()];
            chart.draw_series([PathElement::new(
                vec![(k, low - 0.05), (k, 1.05)],
                color.stroke_width(2),
            )])?;
            chart.draw_series([label(
                format!("{} K = {}", p.name, p.chunk),
                k,
                i + 1,
                color,
            )])?;
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}

/// One dimension of a repaired episode: the recorded samples (grey dots) and the repaired
/// series (colored line and dots) against time.
pub fn repair_example(ex: &RepairExample) -> String {
    svg(|root| {
        root.fill(&WHITE)?;
        let all_t = ex.before_t.iter().chain(&ex.after_t).copied();
        let (t0, t1) = all_t.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| {
            (a.min(t), b.max(t))
        });
        let all_v = ex.before.iter().chain(&ex.after).copied();
        let (v0, v1) = all_v.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
        let pad = ((v1 - v0) * 0.08).max(1e-6);
        let color = verdict_color(ex.verdict);
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!(
                    "Episode {}, {}[{}]: before and after `{}`",
                    ex.episode,
                    ex.channel,
                    ex.dim,
                    verdict_name(ex.verdict)
                ),
                (FONT, 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(span(t0, t1), span(v0 - pad, v1 + pad))?;
        chart
            .configure_mesh()
            .x_desc("time (s)")
            .y_desc(format!("{}[{}]", ex.channel, ex.dim))
            .x_label_formatter(&tick)
            .y_label_formatter(&tick)
            .light_line_style(GRID)
            .label_style((FONT, 12))
            .axis_desc_style((FONT, 14))
            .draw()?;
        chart.draw_series(LineSeries::new(
            ex.after_t.iter().copied().zip(ex.after.iter().copied()),
            color.stroke_width(2),
        ))?;
        chart
            .draw_series(
                ex.after_t
                    .iter()
                    .zip(&ex.after)
                    .map(|(&t, &v)| Circle::new((t, v), 3, color.filled())),
            )?
            .label(format!("after ({} steps)", ex.after.len()))
            .legend(move |(x, y)| Circle::new((x + 10, y), 4, color.filled()));
        chart
            .draw_series(
                ex.before_t
                    .iter()
                    .zip(&ex.before)
                    .map(|(&t, &v)| Circle::new((t, v), 5, BLACK.mix(0.6).stroke_width(1))),
            )?
            .label(format!("before ({} recorded frames)", ex.before.len()))
            .legend(|(x, y)| Circle::new((x + 10, y), 5, BLACK.mix(0.6).stroke_width(1)));
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}
