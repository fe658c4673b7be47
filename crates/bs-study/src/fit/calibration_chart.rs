//! The chart of docs/uncertainty.md: per fit, the predicted deep mean error (mean σ over
//! the deep nodes) against the true one, from the posterior alone and scaled by the
//! held-out landmarks; a calibrated σ lies on the diagonal.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::uncertainty::Row;
use crate::plot::{Figure, PALETTE, err};

/// The figure's data.
pub struct CalibrationChart<'a> {
    pub rows: &'a [Row],
}

impl CalibrationChart<'_> {
    /// The axes' extent: the largest predicted or true error, with a margin.
    fn extent(&self) -> f64 {
        let top = self
            .rows
            .iter()
            .flat_map(|r| [r.raw.predicted, r.scaled.predicted, r.raw.error])
            .fold(0.0f64, f64::max);
        (top * 1.1).max(0.1)
    }
}

impl Figure for CalibrationChart<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let top = self.extent();
        let mut chart = ChartBuilder::on(root)
            .caption("Is σ calibrated? Deep mean error, predicted against true", ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..top, 0.0..top)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("true mean error, nodes > 15 mm from the craniotomy (mm)")
            .y_desc("predicted: mean σ over the same nodes (mm)")
            .draw()
            .map_err(err)?;
        let grey = RGBColor(120, 120, 120);
        chart
            .draw_series(LineSeries::new([(0.0, 0.0), (top, top)], grey.stroke_width(1)))
            .map_err(err)?
            .label("calibrated (predicted = true)")
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], grey.stroke_width(1)));
        let families = ["craniotomy sag", "gravity"];
        for (k, family) in families.into_iter().enumerate() {
            let colour = PALETTE[k];
            let rows: Vec<&Row> =
                self.rows.iter().filter(|r| r.truth.starts_with(family)).collect();
            chart
                .draw_series(rows.iter().map(|r| {
                    Circle::new((r.raw.error, r.raw.predicted), 5, colour.stroke_width(2))
                }))
                .map_err(err)?
                .label(format!("{family}: the posterior alone"))
                .legend(move |(x, y)| Circle::new((x + 10, y), 5, colour.stroke_width(2)));
            chart
                .draw_series(
                    rows.iter().map(|r| {
                        Circle::new((r.raw.error, r.scaled.predicted), 5, colour.filled())
                    }),
                )
                .map_err(err)?
                .label(format!("{family}: scaled by held-out landmarks"))
                .legend(move |(x, y)| Circle::new((x + 10, y), 5, colour.filled()));
            for r in rows.iter().filter(|r| r.scale > 1.0) {
                chart
                    .draw_series(LineSeries::new(
                        [(r.raw.error, r.raw.predicted), (r.raw.error, r.scaled.predicted)],
                        colour.mix(0.5).stroke_width(1),
                    ))
                    .map_err(err)?;
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
