//! The dataset doctor's charts: the action-to-state lag (episodes per lag, and the fit's R² per
//! lag), each episode's units factor, and the quarters of the recording per dimension (shift).

use plotters::prelude::*;

use super::plot::{
    draw_legend, legend_line, span, svg, tick, FONT, GREY, GRID, PALETTE, THRESHOLD_RED,
};
use crate::audit::doctor::DoctorSummary;

/// Episodes per lag (bars) and the mean R² of the state change per lag (line, right axis).
pub fn lag_chart(d: &DoctorSummary) -> String {
    svg(|root| {
        root.fill(&WHITE)?;
        let (lo, hi) = (-5.0f64, 10.0f64);
        let top = d.lag_histogram.values().copied().max().unwrap_or(1).max(1) as f64 * 1.15;
        let mut chart = ChartBuilder::on(root)
            .caption(
                "Action-to-state lag: episodes per lag (bars), mean R² per lag (line)",
                (FONT, 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .right_y_label_area_size(60)
            .build_cartesian_2d(lo - 0.5..hi + 0.5, 0.0..top)?
            .set_secondary_coord(lo - 0.5..hi + 0.5, 0.0..1.05);
        chart
            .configure_mesh()
            .x_desc("lag (steps from an action to the state that first shows it)")
            .y_desc("episodes")
            .x_label_formatter(&tick)
            .y_label_formatter(&tick)
            .light_line_style(GRID)
            .label_style((FONT, 12))
            .axis_desc_style((FONT, 14))
            .draw()?;
        chart
            .configure_secondary_axes()
            .y_desc("R² of the state change")
            .label_style((FONT, 12))
            .axis_desc_style((FONT, 14))
            .draw()?;
        chart
            .draw_series(d.lag_histogram.iter().map(|(&lag, &count)| {
                let color = if Some(lag) == d.lag_mode {
                    PALETTE[0]
                } else {
                    THRESHOLD_RED
                };
                Rectangle::new(
                    [
                        (f64::from(lag) - 0.4, 0.0),
                        (f64::from(lag) + 0.4, count as f64),
                    ],
                    color.mix(0.75).filled(),
                )
            }))?
            .label("episodes at that lag (red: not the mode)")
            .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], PALETTE[0].filled()));
        chart
            .draw_secondary_series(LineSeries::new(
                d.lag_curve.iter().map(|&(lag, r2)| (f64::from(lag), r2)),
                PALETTE[1].stroke_width(2),
            ))?
            .label("mean R²")
            .legend(legend_line(PALETTE[1], 2));
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}

/// Each episode's units factor (log scale), the thresholds as dashed lines.
pub fn units_chart(d: &DoctorSummary, ratio: f64) -> String {
    svg(|root| {
        root.fill(&WHITE)?;
        let n = d.units.len().max(1) as f64;
        let lo = d.units.iter().map(|u| u.1).fold(1.0 / ratio, f64::min) / 1.5;
        let hi = d.units.iter().map(|u| u.1).fold(ratio, f64::max) * 1.5;
        let mut chart = ChartBuilder::on(root)
            .caption(
                "Action units per episode, against the dataset (1 = the same)",
                (FONT, 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(span(-0.5, n - 0.5), (lo..hi).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("episode (position in source order)")
            .y_desc("units factor (log scale)")
            .x_label_formatter(&tick)
            .y_label_formatter(&tick)
            .light_line_style(GRID)
            .label_style((FONT, 12))
            .axis_desc_style((FONT, 14))
            .draw()?;
        let off = |u: f64| u > ratio || u < 1.0 / ratio;
        chart
            .draw_series(d.units.iter().enumerate().map(|(i, &(_, u))| {
                Circle::new(
                    (i as f64, u),
                    3,
                    if off(u) {
                        THRESHOLD_RED.filled()
                    } else {
                        GREY.filled()
                    },
                )
            }))?
            .label("episode (red: flagged units)")
            .legend(|(x, y)| Circle::new((x + 10, y), 4, GREY.filled()));
        for t in [ratio, 1.0 / ratio] {
            chart.draw_series(DashedLineSeries::new(
                [(-0.5, t), (n - 0.5, t)],
                8,
                5,
                THRESHOLD_RED.stroke_width(1),
            ))?;
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}

/// Per dimension, each quarter's median episode mean in robust std from the dataset's.
pub fn shift_chart(d: &DoctorSummary, threshold: f64) -> String {
    svg(|root| {
        root.fill(&WHITE)?;
        let most = d
            .shift
            .iter()
            .flat_map(|s| s.deviations.iter().map(|v| v.abs()))
            .fold(threshold, f64::max)
            * 1.2;
        let mut chart = ChartBuilder::on(root)
            .caption(
                "Shift across the recording: each quarter's median episode mean",
                (FONT, 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(0.5..4.5, -most..most)?;
        chart
            .configure_mesh()
            .x_desc("quarter of the episodes, in recording order")
            .y_desc("robust std from the dataset")
            .x_label_formatter(&tick)
            .y_label_formatter(&tick)
            .light_line_style(GRID)
            .label_style((FONT, 12))
            .axis_desc_style((FONT, 14))
            .draw()?;
        for (k, s) in d.shift.iter().enumerate() {
            let color = PALETTE[k % PALETTE.len()];
            let series = chart.draw_series(LineSeries::new(
                s.deviations
                    .iter()
                    .enumerate()
                    .map(|(q, &v)| (q as f64 + 1.0, v)),
                color.stroke_width(1),
            ))?;
            if k < 8 {
                series
                    .label(format!("{}[{}]", s.channel, s.dim))
                    .legend(legend_line(color, 1));
            }
        }
        for t in [threshold, -threshold] {
            chart.draw_series(DashedLineSeries::new(
                [(0.5, t), (4.5, t)],
                8,
                5,
                THRESHOLD_RED.stroke_width(1),
            ))?;
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}
