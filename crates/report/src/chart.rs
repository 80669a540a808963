//! Line charts with plotters: the same drawing to SVG (text left to the viewer's fonts) and to PNG (text
//! through an embedded DejaVu Sans subset, so no system font is needed).

use pganeus_io::Image;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::sync::Once;

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mark {
    Line,
    Dashed,
    /// Points only (values without an order between them).
    Points,
}

/// One named series of `(x, y)` points; non-finite points are left out.
#[derive(Clone, Debug)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub mark: Mark,
    /// The series' colour (default: the palette's, by position).
    pub color: Option<[u8; 3]>,
}

impl Series {
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>, mark: Mark) -> Self {
        Self {
            label: label.into(),
            points,
            mark,
            color: None,
        }
    }

    pub fn colored(self, rgb: [u8; 3]) -> Self {
        Self {
            color: Some(rgb),
            ..self
        }
    }
}

/// A chart: title, axis names and series. With `equal_axes`, a unit on x is as long as a unit on y (maps).
#[derive(Clone, Debug, Default)]
pub struct Chart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    pub equal_axes: bool,
}

/// Colours by series index: the first four are the paper's truth / PA / GA / PGA order.
const PALETTE: [RGBColor; 8] = [
    RGBColor(30, 30, 30),
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(23, 190, 207),
];

const FONT: &[u8] = include_bytes!("../assets/DejaVuSans-subset.ttf");

/// plotters' text goes through ab_glyph, which knows only the fonts registered with it.
fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The font is compiled in and known to parse: a failure here is a broken build.
        plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
            .unwrap_or_else(|_| panic!("the embedded DejaVu Sans subset does not parse"));
    });
}

impl Chart {
    pub fn new(title: impl Into<String>, x_label: impl Into<String>, y_label: impl Into<String>) -> Self {
        Self {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            ..Default::default()
        }
    }

    pub fn with(mut self, series: Series) -> Self {
        self.series.push(series);
        self
    }

    /// Whether any series has a point to draw.
    pub fn is_empty(&self) -> bool {
        self.finite_points().next().is_none()
    }

    fn finite_points(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.series
            .iter()
            .flat_map(|s| s.points.iter().copied())
            .filter(|(x, y)| x.is_finite() && y.is_finite())
    }

    /// The drawing as an SVG document of `width × height` pixels.
    pub fn svg(&self, width: u32, height: u32) -> Result<String, String> {
        register_font();
        let mut out = String::new();
        {
            let root = SVGBackend::with_string(&mut out, (width, height)).into_drawing_area();
            self.draw(&root, (width, height))?;
        }
        Ok(out)
    }

    /// The drawing as an RGB image of `width × height` pixels.
    pub fn png(&self, width: u32, height: u32) -> Result<Image, String> {
        register_font();
        let mut data = vec![255u8; width as usize * height as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut data, (width, height)).into_drawing_area();
            self.draw(&root, (width, height))?;
        }
        Ok(Image {
            width,
            height,
            channels: 3,
            data,
        })
    }

    /// The axis ranges: the data's with a margin, widened on one axis for `equal_axes`.
    fn ranges(&self, size: (u32, u32)) -> ((f64, f64), (f64, f64)) {
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for (x, y) in self.finite_points() {
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
        if x0 > x1 {
            return ((0.0, 1.0), (0.0, 1.0));
        }
        let pad = |a: f64, b: f64| {
            let span = (b - a).max(1e-9 * (a.abs() + b.abs()).max(1e-12));
            (a - 0.05 * span, b + 0.05 * span)
        };
        let ((x0, x1), (y0, y1)) = (pad(x0, x1), pad(y0, y1));
        if !self.equal_axes {
            return ((x0, x1), (y0, y1));
        }
        // The plotting area is the image less the label areas and margins set in `draw`.
        let (w, h) = ((size.0 as f64 - 85.0).max(1.0), (size.1 as f64 - 80.0).max(1.0));
        let per_px = ((x1 - x0) / w).max((y1 - y0) / h);
        let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
        (
            (cx - 0.5 * per_px * w, cx + 0.5 * per_px * w),
            (cy - 0.5 * per_px * h, cy + 0.5 * per_px * h),
        )
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, size: (u32, u32)) -> Result<(), String> {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| format!("chart {:?}: {e}", self.title);
        root.fill(&WHITE).map_err(err)?;
        let ((x0, x1), (y0, y1)) = self.ranges(size);
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(55)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .label_style(("sans-serif", 12))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(err)?;
        for (i, s) in self.series.iter().enumerate() {
            let color = s
                .color
                .map_or(PALETTE[i % PALETTE.len()], |[r, g, b]| RGBColor(r, g, b));
            let pts: Vec<(f64, f64)> = s
                .points
                .iter()
                .copied()
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .collect();
            let line = color.stroke_width(2);
            let drawn = match s.mark {
                Mark::Line => chart.draw_series(LineSeries::new(pts, line)).map_err(err)?,
                Mark::Dashed => chart.draw_series(DashedLineSeries::new(pts, 6, 4, line)).map_err(err)?,
                Mark::Points => chart
                    .draw_series(pts.into_iter().map(|p| Circle::new(p, 3, color.filled())))
                    .map_err(err)?,
            };
            let mark = s.mark;
            drawn.label(s.label.clone()).legend(move |(x, y)| match mark {
                Mark::Points => Circle::new((x + 8, y), 3, color.filled()).into_dyn(),
                _ => PathElement::new(vec![(x, y), (x + 16, y)], line).into_dyn(),
            });
        }
        if self.series.len() > 1 || self.series.iter().any(|s| !s.label.is_empty()) {
            chart
                .configure_series_labels()
                .label_font(("sans-serif", 12))
                .background_style(WHITE.mix(0.85))
                .border_style(RGBColor(180, 180, 180))
                .position(SeriesLabelPosition::UpperRight)
                .draw()
                .map_err(err)?;
        }
        root.present().map_err(err)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Chart {
        Chart::new("height over time", "time (s)", "z (m)")
            .with(Series::new(
                "truth",
                (0..30)
                    .map(|k| (k as f64 / 30.0, 0.1 - 0.5 * 9.81 * (k as f64 / 30.0).powi(2)))
                    .collect(),
                Mark::Line,
            ))
            .with(Series::new(
                "fit",
                (0..30)
                    .map(|k| (k as f64 / 30.0, 0.1 - 0.5 * 9.7 * (k as f64 / 30.0).powi(2)))
                    .collect(),
                Mark::Dashed,
            ))
    }

    #[test]
    fn a_chart_draws_to_svg_with_its_text_and_to_png_with_ink() {
        let c = sample();
        let svg = c.svg(480, 320).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("height over time") && svg.contains("truth"));
        let png = c.png(480, 320).unwrap();
        png.check().unwrap();
        // Axes, lines and text put dark pixels on the white page; the series colours are there too.
        let dark = png.data.chunks(3).filter(|p| p.iter().all(|&v| v < 100)).count();
        assert!(dark > 500, "{dark} dark pixels");
        let red = png
            .data
            .chunks(3)
            .filter(|p| p[0] > 180 && p[1] < 80 && p[2] < 80)
            .count();
        assert_eq!(red, 0, "no fourth series, no red");
        let blue = png.data.chunks(3).filter(|p| p[2] > 150 && p[0] < 80).count();
        assert!(blue > 50, "the second series is drawn: {blue}");
    }

    #[test]
    fn equal_axes_give_one_scale_to_both_axes() {
        let mut c = Chart::new("top view", "x (m)", "y (m)").with(Series::new(
            "path",
            vec![(0.0, 0.0), (1.0, 0.1)],
            Mark::Line,
        ));
        c.equal_axes = true;
        let ((x0, x1), (y0, y1)) = c.ranges((485, 380));
        let per_x = (x1 - x0) / 400.0;
        let per_y = (y1 - y0) / 300.0;
        assert!((per_x / per_y - 1.0).abs() < 1e-9, "{per_x} {per_y}");
        assert!(x0 < 0.0 && x1 > 1.0 && y0 < 0.0 && y1 > 0.1);
        assert!(Chart::new("", "", "").is_empty());
    }
}
