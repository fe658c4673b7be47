//! The chart of docs/fit.md: the fit's deep error against the scan's noise, one line per
//! coverage, with the coverage oracles and no correction as horizontal references.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::study::{Oracle, Row};
use crate::plot::{Figure, PALETTE, err};

/// The figure's data.
pub struct NoiseChart<'a> {
    pub rows: &'a [Row],
    pub oracles: &'a [Oracle],
    pub none: f64,
}

impl Figure for NoiseChart<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let y1 = self.none * 1.15;
        let mut chart = ChartBuilder::on(root)
            .caption("Fit of a scanned craniotomy: error at deep nodes", ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(-0.1f64..2.1, 0.0..y1)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("scan noise σ (mm per axis)")
            .y_desc("mean error, nodes > 15 mm from the craniotomy (mm)")
            .draw()
            .map_err(err)?;
        let grey = RGBColor(120, 120, 120);
        chart
            .draw_series(LineSeries::new(
                [(-0.1, self.none), (2.1, self.none)],
                grey.stroke_width(2),
            ))
            .map_err(err)?
            .label("no correction")
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], grey.stroke_width(2)));
        for (k, coverage) in [1.0, 0.5, 0.25].into_iter().enumerate() {
            let colour = PALETTE[k];
            let points: Vec<(f64, f64)> = self
                .rows
                .iter()
                .filter(|r| {
                    r.group == "noise × coverage" && r.case.coverage == coverage && r.fit.is_ok()
                })
                .map(|r| (r.case.sigma, r.fit.as_ref().map(|e| e.0).unwrap_or(0.0)))
                .collect();
            chart
                .draw_series(LineSeries::new(points.clone(), colour.stroke_width(2)))
                .map_err(err)?
                .label(format!("fit, {} % of the window scanned", coverage * 100.0))
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 20, y)], colour.stroke_width(2))
                });
            chart
                .draw_series(points.iter().map(|&p| Circle::new(p, 4, colour.filled())))
                .map_err(err)?;
            if let Some((_, Ok((mean, ..)))) = self.oracles.iter().find(|(c, _)| *c == coverage) {
                let m = *mean;
                chart
                    .draw_series(DashedLineSeries::new(
                        [(-0.1, m), (2.1, m)],
                        6,
                        4,
                        colour.stroke_width(1),
                    ))
                    .map_err(err)?
                    .label(format!("exact vectors of the {} % imposed (oracle)", coverage * 100.0))
                    .legend(move |(x, y)| {
                        PathElement::new([(x, y), (x + 20, y)], colour.stroke_width(1))
                    });
            }
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperLeft)
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(err)?;
        Ok(())
    }
}
