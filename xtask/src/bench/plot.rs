//! The log–log plot of error against time, as a self-contained SVG (written by hand: a few
//! dozen lines, no fonts or system libraries needed).
use std::fmt::Write as _;

pub struct Series {
    pub label: String,
    /// (seconds, relMSE) points, in order of time.
    pub points: Vec<(f64, f64)>,
    pub dashed: bool,
}

const COLORS: [&str; 10] = [
    "#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#7f7f7f", "#bcbd22",
];

fn decades(lo: f64, hi: f64) -> (f64, f64) {
    (lo.log10().floor(), hi.log10().ceil().max(lo.log10().floor() + 1.0))
}

/// An SVG plot of `series` (log10 axes), with horizontal reference lines `hlines`
/// (value, label).
pub fn svg(title: &str, x_label: &str, series: &[Series], hlines: &[(f64, String)]) -> String {
    let (w, h) = (760.0, 480.0);
    let (left, right, top, bottom) = (70.0, 230.0, 40.0, 50.0);
    let pts = || {
        series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|p| p.0 > 0.0 && p.1 > 0.0)
    };
    let xs: Vec<f64> = pts().map(|p| p.0).collect();
    let ys: Vec<f64> = pts()
        .map(|p| p.1)
        .chain(hlines.iter().map(|l| l.0).filter(|v| *v > 0.0))
        .collect();
    let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    let max = |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let (x0, x1) = if xs.is_empty() {
        (0.0, 1.0)
    } else {
        decades(min(&xs), max(&xs))
    };
    let (y0, y1) = if ys.is_empty() {
        (0.0, 1.0)
    } else {
        decades(min(&ys), max(&ys))
    };
    let px = |x: f64| left + (x.log10() - x0) / (x1 - x0) * (w - left - right);
    let py = |y: f64| top + (y1 - y.log10()) / (y1 - y0) * (h - top - bottom);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    let _ = writeln!(s, r#"<text x="{}" y="22" font-size="15">{}</text>"#, left, esc(title));
    // Grid and tick labels at every decade.
    for d in (x0 as i32)..=(x1 as i32) {
        let x = px(10f64.powi(d));
        let _ = writeln!(
            s,
            r##"<line x1="{x}" y1="{top}" x2="{x}" y2="{}" stroke="#ddd"/><text x="{x}" y="{}" text-anchor="middle">1e{d}</text>"##,
            h - bottom,
            h - bottom + 16.0
        );
    }
    for d in (y0 as i32)..=(y1 as i32) {
        let y = py(10f64.powi(d));
        let _ = writeln!(
            s,
            r##"<line x1="{left}" y1="{y}" x2="{}" y2="{y}" stroke="#ddd"/><text x="{}" y="{}" text-anchor="end">1e{d}</text>"##,
            w - right,
            left - 6.0,
            y + 4.0
        );
    }
    let _ = writeln!(
        s,
        r#"<rect x="{left}" y="{top}" width="{}" height="{}" fill="none" stroke="black"/>"#,
        w - left - right,
        h - top - bottom
    );
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
        left + (w - left - right) / 2.0,
        h - 10.0,
        esc(x_label)
    );
    let _ = writeln!(
        s,
        r#"<text x="16" y="{}" transform="rotate(-90 16 {})" text-anchor="middle">relMSE against the reference</text>"#,
        top + (h - top - bottom) / 2.0,
        top + (h - top - bottom) / 2.0
    );
    for (v, label) in hlines.iter().filter(|l| l.0 > 0.0) {
        let y = py(*v);
        let _ = writeln!(
            s,
            r##"<line x1="{left}" y1="{y}" x2="{}" y2="{y}" stroke="#555" stroke-dasharray="2,3"/><text x="{}" y="{}" font-size="10" fill="#555">{}</text>"##,
            w - right,
            left + 4.0,
            y - 3.0,
            esc(label)
        );
    }
    for (i, se) in series.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        let mut sorted = se.points.clone();
        sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
        let p: Vec<String> = sorted
            .iter()
            .filter(|p| p.0 > 0.0 && p.1 > 0.0)
            .map(|&(x, y)| format!("{:.1},{:.1}", px(x), py(y)))
            .collect();
        let dash = if se.dashed { r#" stroke-dasharray="6,3""# } else { "" };
        let _ = writeln!(
            s,
            r#"<polyline points="{}" fill="none" stroke="{color}" stroke-width="2"{dash}/>"#,
            p.join(" ")
        );
        for q in &p {
            let (cx, cy) = q.split_once(',').expect("x,y");
            let _ = writeln!(s, r#"<circle cx="{cx}" cy="{cy}" r="3" fill="{color}"/>"#);
        }
        let ly = top + 10.0 + 18.0 * i as f64;
        let lx = w - right + 12.0;
        let _ = writeln!(
            s,
            r#"<line x1="{lx}" y1="{ly}" x2="{}" y2="{ly}" stroke="{color}" stroke-width="2"{dash}/><text x="{}" y="{}">{}</text>"#,
            lx + 22.0,
            lx + 28.0,
            ly + 4.0,
            esc(&se.label)
        );
    }
    s.push_str("</svg>\n");
    s
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    #[test]
    fn svg_has_one_polyline_per_series() {
        let series = vec![
            super::Series {
                label: "pt".into(),
                points: vec![(1.0, 0.1), (2.0, 0.05)],
                dashed: false,
            },
            super::Series {
                label: "vbl <gpu>".into(),
                points: vec![(1.5, 0.2)],
                dashed: true,
            },
        ];
        let s = super::svg("t", "x", &series, &[(1e-3, "reference".into())]);
        assert_eq!(s.matches("<polyline").count(), 2);
        assert!(s.contains("vbl &lt;gpu&gt;"));
        assert!(s.ends_with("</svg>\n"));
    }
}
