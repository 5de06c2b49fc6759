//! PNG text: plotters 0.3.7 places each ab_glyph glyph at the truncated pen position and drops
//! the glyph's left side bearing, so letters are unevenly spaced. [`TextFix`] wraps the bitmap
//! backend and draws text itself with the bearings and a fractional pen, in the DejaVu Sans file
//! shipped in `assets/fonts`.

use std::sync::Once;

use ab_glyph::{Font, FontRef, ScaleFont, point};
use plotters::prelude::*;
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingErrorKind, text_anchor::HPos, text_anchor::VPos,
};

/// The family name every figure's text uses (registered with plotters as the shipped font).
pub(super) const FONT: &str = "sans-serif";

/// DejaVu Sans, shipped in `assets/fonts` (freely redistributable).
pub(super) static FONT_BYTES: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");

pub(super) fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The shipped font is valid; if registration failed, PNG text would be missing, which the
        // tests would catch.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES);
    });
}

/// A one-pixel pen of a colour, for [`TextFix::draw_path`].
struct Pen(BackendColor);

impl BackendStyle for Pen {
    fn color(&self) -> BackendColor {
        self.0
    }
    fn stroke_width(&self) -> u32 {
        1
    }
}

/// The bitmap backend with correct glyph placement (see the module docs): every call but
/// `draw_text` goes to plotters' `BitMapBackend`.
pub(super) struct TextFix<'a> {
    /// plotters' bitmap backend, drawing everything but text.
    pub(super) inner: BitMapBackend<'a>,
    /// The shipped font, for the glyphs' outlines and metrics.
    pub(super) font: FontRef<'static>,
}

impl DrawingBackend for TextFix<'_> {
    type ErrorType = <BitMapBackend<'static> as DrawingBackend>::ErrorType;

    fn get_size(&self) -> (u32, u32) {
        self.inner.get_size()
    }
    fn ensure_prepared(&mut self) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.ensure_prepared()
    }
    fn present(&mut self) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.present()
    }
    fn draw_pixel(
        &mut self,
        point: BackendCoord,
        color: BackendColor,
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_pixel(point, color)
    }
    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_line(from, to, style)
    }
    fn draw_rect<S: BackendStyle>(
        &mut self,
        upper_left: BackendCoord,
        bottom_right: BackendCoord,
        style: &S,
        fill: bool,
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_rect(upper_left, bottom_right, style, fill)
    }
    /// Wide lines as `w` one-pixel lines side by side: plotters fills a wide path as a polygon
    /// with vertices truncated to whole pixels, so a shallow line of short segments (a geodesic
    /// sampled finely) loses most of its pixels and shows as sparse dots.
    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        let w = style.stroke_width() as i32;
        if w <= 1 {
            return self.inner.draw_path(path, style);
        }
        let pen = Pen(style.color());
        let points: Vec<BackendCoord> = path.into_iter().collect();
        for seg in points.windows(2) {
            let (a, b) = (seg[0], seg[1]);
            let steep = (b.1 - a.1).abs() > (b.0 - a.0).abs();
            for k in 0..w {
                let o = k - (w - 1) / 2;
                let (p, q) = if steep { ((a.0 + o, a.1), (b.0 + o, b.1)) } else { ((a.0, a.1 + o), (b.0, b.1 + o)) };
                self.inner.draw_line(p, q, &pen)?;
            }
        }
        Ok(())
    }
    fn draw_circle<S: BackendStyle>(
        &mut self,
        center: BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_circle(center, radius, style, fill)
    }
    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.fill_polygon(vert, style)
    }
    fn blit_bitmap(
        &mut self,
        pos: BackendCoord,
        (iw, ih): (u32, u32),
        src: &[u8],
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.blit_bitmap(pos, (iw, ih), src)
    }

    /// Lays the glyphs out on a fractional pen with kerning and draws each at its own pixel
    /// bounds (which include the left side bearing). The box and the anchor are those of
    /// plotters' layout (advance widths and kerning, height size/1.24), so text sits where the
    /// chart expects it.
    fn draw_text<TStyle: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &TStyle,
        pos: BackendCoord,
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        let color = style.color();
        if color.alpha == 0.0 {
            return Ok(());
        }
        let size = style.size() as f32;
        let scaled = self.font.as_scaled(size);
        let mut glyphs = Vec::with_capacity(text.len());
        let mut pen = 0.0f32;
        let mut prev = None;
        for c in text.chars() {
            let id = scaled.glyph_id(c);
            if let Some(p) = prev {
                pen += scaled.kern(p, id);
            }
            glyphs.push(id.with_scale_and_position(size, point(pen, 0.0)));
            pen += scaled.h_advance(id);
            prev = Some(id);
        }
        let width = pen as i32;
        let height = (f64::from(size) / 1.24) as i32;
        let dx = match style.anchor().h_pos {
            HPos::Left => 0,
            HPos::Right => -width,
            HPos::Center => -width / 2,
        };
        let dy = match style.anchor().v_pos {
            VPos::Top => 0,
            VPos::Center => -height / 2,
            VPos::Bottom => -height,
        };
        // plotters puts the baseline half the font size below the layout's top.
        let baseline = size / 2.0;
        let trans = style.transform();
        let (w, h) = self.inner.get_size();
        for g in glyphs {
            let Some(outline) = self.font.outline_glyph(g) else { continue };
            let b = outline.px_bounds();
            let mut pixels = Vec::new();
            outline.draw(|x, y, c| pixels.push((x as i32 + b.min.x as i32, y as i32 + (b.min.y + baseline) as i32, c)));
            for (x, y, c) in pixels {
                let (x, y) = trans.transform(x + dx, y + dy);
                let (x, y) = (pos.0 + x, pos.1 + y);
                if x >= 0 && x < w as i32 && y >= 0 && y < h as i32 && c > 0.0 {
                    let alpha = color.alpha * f64::from(c.min(1.0));
                    self.inner.draw_pixel((x, y), BackendColor { alpha, rgb: color.rgb })?;
                }
            }
        }
        Ok(())
    }
}
