//! A minimal SVG plotting kit (plain SVG 1.1, no dependency): a writer, axes with round ticks
//! and unit labels, and legends. The plots of the reports are drawn with it.
//!
//! Ticks are "nice numbers" (Heckbert, "Nice numbers for graph labels", Graphics Gems, 1990):
//! a step of 1, 2 or 5 times a power of ten giving about the asked number of ticks, labelled
//! with as many decimals as the step needs.

use std::fmt::Write as _;

use nalgebra::Vector2;

/// Colours of the cameras and series (matplotlib's `tab10`).
pub(crate) const COLOURS: [&str; 10] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf",
];

/// The colour of series `i`.
pub(crate) fn colour(i: usize) -> &'static str {
    COLOURS[i % COLOURS.len()]
}

/// Escapes text for an XML text node or attribute.
pub(crate) fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A minimal SVG writer.
pub(crate) struct Svg {
    s: String,
}

impl Svg {
    /// A white canvas of `width` x `height` SVG units.
    pub(crate) fn new(width: f64, height: f64) -> Self {
        let mut s = String::new();
        let _ = write!(
            s,
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width:.0}\" height=\"{height:.0}\" \
             viewBox=\"0 0 {width:.0} {height:.0}\" font-family=\"sans-serif\" font-size=\"12\">\n\
             <rect width=\"{width:.0}\" height=\"{height:.0}\" fill=\"white\"/>\n"
        );
        Self { s }
    }

    /// A line segment.
    pub(crate) fn line(&mut self, a: Vector2<f64>, b: Vector2<f64>, stroke: &str, width: f64) {
        let _ = writeln!(
            self.s,
            "<line x1=\"{:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"{stroke}\" \
             stroke-width=\"{width}\"/>",
            a.x, a.y, b.x, b.y
        );
    }

    /// A filled disc.
    pub(crate) fn circle(&mut self, c: Vector2<f64>, r: f64, fill: &str) {
        let _ = writeln!(
            self.s,
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"{r}\" fill=\"{fill}\"/>",
            c.x, c.y
        );
    }

    /// A circle outline.
    pub(crate) fn ring(&mut self, c: Vector2<f64>, r: f64, stroke: &str) {
        let _ = writeln!(
            self.s,
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"{r}\" fill=\"none\" stroke=\"{stroke}\" \
             stroke-width=\"1.5\"/>",
            c.x, c.y
        );
    }

    /// An open polyline.
    pub(crate) fn polyline(&mut self, points: &[Vector2<f64>], stroke: &str, width: f64) {
        if points.is_empty() {
            return;
        }
        let coords: Vec<String> = points
            .iter()
            .map(|p| format!("{:.1},{:.1}", p.x, p.y))
            .collect();
        let _ = writeln!(
            self.s,
            "<polyline points=\"{}\" fill=\"none\" stroke=\"{stroke}\" stroke-width=\"{width}\"/>",
            coords.join(" ")
        );
    }

    /// Text at `p`, anchored `start`, `middle` or `end`.
    pub(crate) fn text(&mut self, p: Vector2<f64>, anchor: &str, fill: &str, text: &str) {
        let _ = writeln!(
            self.s,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"{anchor}\" fill=\"{fill}\">{}</text>",
            p.x,
            p.y,
            xml_escape(text)
        );
    }

    /// Text turned 90 degrees counter-clockwise about `p` (a y-axis label).
    pub(crate) fn vertical_text(&mut self, p: Vector2<f64>, text: &str) {
        let _ = writeln!(
            self.s,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\" transform=\"rotate(-90 {:.1} \
             {:.1})\">{}</text>",
            p.x,
            p.y,
            p.x,
            p.y,
            xml_escape(text)
        );
    }

    /// A rectangle outline (`fill` may be `none`).
    pub(crate) fn rect(
        &mut self,
        origin: Vector2<f64>,
        size: Vector2<f64>,
        fill: &str,
        stroke: &str,
    ) {
        let _ = writeln!(
            self.s,
            "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"{fill}\" \
             stroke=\"{stroke}\"/>",
            origin.x, origin.y, size.x, size.y
        );
    }

    /// Raw SVG (a group, a title).
    pub(crate) fn raw(&mut self, text: &str) {
        self.s.push_str(text);
        self.s.push('\n');
    }

    /// The document.
    pub(crate) fn finish(mut self) -> String {
        self.s.push_str("</svg>\n");
        self.s
    }
}

/// Round tick values covering `[lo, hi]`: about `count` of them, a step of 1, 2 or 5 times a
/// power of ten. Returns the ticks inside the range and the step.
pub(crate) fn nice_ticks(lo: f64, hi: f64, count: usize) -> (Vec<f64>, f64) {
    let span = hi - lo;
    if !(span.is_finite() && span > 0.0) || count == 0 {
        return (vec![lo], 1.0);
    }
    let raw = span / count as f64;
    let decade = 10f64.powf(raw.log10().floor());
    let step = decade
        * match raw / decade {
            m if m < 1.5 => 1.0,
            m if m < 3.0 => 2.0,
            m if m < 7.0 => 5.0,
            _ => 10.0,
        };
    let first = (lo / step).ceil();
    let last = (hi / step).floor();
    // The count is small (about `count`): the cast of a finite, bounded float is exact.
    #[allow(clippy::cast_possible_truncation)]
    let n = (last - first) as i64;
    let ticks = (0..=n.max(0))
        .map(|k| (first + k as f64) * step)
        // -0.0 prints as "-0".
        .map(|t| if t == 0.0 { 0.0 } else { t })
        .collect();
    (ticks, step)
}

/// A tick label: as many decimals as the step needs.
pub(crate) fn tick_label(value: f64, step: f64) -> String {
    let decimals = if step >= 1.0 {
        0
    } else {
        // A step of 0.05 needs 2 decimals, 0.2 needs 1.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let d = (-step.log10()).ceil().max(0.0) as usize;
        d
    };
    format!("{value:.decimals$}")
}

/// A plot area mapping data coordinates to the page (y up), with axes drawn around it.
pub(crate) struct Axes {
    /// Top-left corner of the plot area on the page.
    pub(crate) origin: Vector2<f64>,
    /// Width and height of the plot area on the page.
    pub(crate) size: Vector2<f64>,
    /// Data coordinates at the plot area's bottom-left corner.
    pub(crate) lo: Vector2<f64>,
    /// Data coordinates at its top-right corner.
    pub(crate) hi: Vector2<f64>,
}

impl Axes {
    /// Axes over `[lo, hi]`, each axis scaled on its own.
    pub(crate) fn new(
        origin: Vector2<f64>,
        size: Vector2<f64>,
        lo: Vector2<f64>,
        hi: Vector2<f64>,
    ) -> Self {
        Self {
            origin,
            size,
            lo,
            hi,
        }
    }

    /// Axes over a square area of side `side` showing `[lo, hi]` with equal scales on both
    /// axes (a map), the data centred with a 5% margin.
    pub(crate) fn equal(
        origin: Vector2<f64>,
        side: f64,
        lo: Vector2<f64>,
        hi: Vector2<f64>,
    ) -> Self {
        let span = (hi - lo).max().max(1e-9) * 1.1;
        let centre = (lo + hi) / 2.0;
        let half = Vector2::repeat(span / 2.0);
        Self::new(origin, Vector2::repeat(side), centre - half, centre + half)
    }

    /// Page coordinates of a data point.
    pub(crate) fn map(&self, p: Vector2<f64>) -> Vector2<f64> {
        let f = (p - self.lo).component_div(&(self.hi - self.lo));
        Vector2::new(
            self.origin.x + f.x * self.size.x,
            self.origin.y + (1.0 - f.y) * self.size.y,
        )
    }

    /// True when a data point falls inside the plot area.
    pub(crate) fn contains(&self, p: Vector2<f64>) -> bool {
        let inside = |v: f64, a: f64, b: f64| v >= a.min(b) && v <= a.max(b);
        inside(p.x, self.lo.x, self.hi.x) && inside(p.y, self.lo.y, self.hi.y)
    }

    /// The frame, light grid lines and labelled round ticks on both axes, and the axis labels
    /// (with their units).
    pub(crate) fn draw(&self, svg: &mut Svg, x_label: &str, y_label: &str) {
        svg.rect(self.origin, self.size, "none", "#444");
        // Ticks over the range whichever way the axis runs (an image's v runs down).
        let range = |a: f64, b: f64| (a.min(b), a.max(b));
        let (x_min, x_max) = range(self.lo.x, self.hi.x);
        let (y_min, y_max) = range(self.lo.y, self.hi.y);
        let (xt, xs) = nice_ticks(x_min, x_max, 8);
        for x in xt {
            let bottom = self.map(Vector2::new(x, self.lo.y));
            let top = Vector2::new(bottom.x, self.origin.y);
            svg.line(top, bottom, "#e4e4e4", 0.5);
            svg.line(bottom, bottom + Vector2::new(0.0, 5.0), "#444", 1.0);
            svg.text(
                bottom + Vector2::new(0.0, 17.0),
                "middle",
                "#000",
                &tick_label(x, xs),
            );
        }
        let (yt, ys) = nice_ticks(y_min, y_max, 8);
        for y in yt {
            let left = self.map(Vector2::new(self.lo.x, y));
            let right = Vector2::new(self.origin.x + self.size.x, left.y);
            svg.line(left, right, "#e4e4e4", 0.5);
            svg.line(left, left - Vector2::new(5.0, 0.0), "#444", 1.0);
            svg.text(
                left + Vector2::new(-8.0, 4.0),
                "end",
                "#000",
                &tick_label(y, ys),
            );
        }
        svg.text(
            Vector2::new(
                self.origin.x + self.size.x / 2.0,
                self.origin.y + self.size.y + 36.0,
            ),
            "middle",
            "#000",
            x_label,
        );
        svg.vertical_text(
            Vector2::new(self.origin.x - 46.0, self.origin.y + self.size.y / 2.0),
            y_label,
        );
    }
}

/// How a legend entry is drawn.
#[derive(Clone, Copy)]
pub(crate) enum Mark {
    /// A dot.
    Dot,
    /// A ring (an outlier).
    Ring,
    /// A line.
    Line,
}

/// A legend box in the top-right corner of `axes`: one row per `(mark, colour, label)`.
pub(crate) fn legend(svg: &mut Svg, axes: &Axes, entries: &[(Mark, &str, String)]) {
    let width = 12.0 + 7.0 * entries.iter().map(|e| e.2.len()).max().unwrap_or(0) as f64 + 30.0;
    let height = 8.0 + 16.0 * entries.len() as f64;
    let origin = Vector2::new(
        axes.origin.x + axes.size.x - width - 8.0,
        axes.origin.y + 8.0,
    );
    svg.rect(origin, Vector2::new(width, height), "#ffffffe6", "#999");
    for (k, (mark, colour, label)) in entries.iter().enumerate() {
        let y = origin.y + 14.0 + 16.0 * k as f64;
        let x = origin.x + 10.0;
        match mark {
            Mark::Dot => svg.circle(Vector2::new(x + 8.0, y - 4.0), 3.0, colour),
            Mark::Ring => svg.ring(Vector2::new(x + 8.0, y - 4.0), 4.0, colour),
            Mark::Line => svg.line(
                Vector2::new(x, y - 4.0),
                Vector2::new(x + 16.0, y - 4.0),
                colour,
                2.0,
            ),
        }
        svg.text(Vector2::new(x + 24.0, y), "start", "#000", label);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        let (t, step) = nice_ticks(0.0, 1.37, 5);
        assert_eq!(step, 0.2);
        assert_eq!(t.len(), 7);
        assert_eq!(tick_label(t[3], step), "0.6");
        let (t, step) = nice_ticks(-123.0, 456.0, 8);
        assert_eq!(step, 100.0);
        assert_eq!(t.first().copied(), Some(-100.0));
        assert_eq!(t.last().copied(), Some(400.0));
        assert_eq!(tick_label(0.0, step), "0");
        let (t, step) = nice_ticks(0.001, 0.0042, 4);
        assert_eq!(step, 0.001);
        assert_eq!(tick_label(t[1], step), "0.002");
        assert_eq!(nice_ticks(1.0, 1.0, 5).0, vec![1.0]);
    }

    #[test]
    fn axes_map_data_to_the_page_with_y_up() {
        let a = Axes::new(
            Vector2::new(10.0, 20.0),
            Vector2::new(100.0, 50.0),
            Vector2::new(0.0, 0.0),
            Vector2::new(10.0, 5.0),
        );
        assert_eq!(a.map(Vector2::new(0.0, 0.0)), Vector2::new(10.0, 70.0));
        assert_eq!(a.map(Vector2::new(10.0, 5.0)), Vector2::new(110.0, 20.0));
        let mut svg = Svg::new(200.0, 120.0);
        a.draw(&mut svg, "x [m]", "y [m]");
        let s = svg.finish();
        assert!(s.contains(">x [m]</text>") && s.contains("rotate(-90"));
    }
}
