//! A plotters backend on a `<canvas>` 2-D context through web-sys: what draws the page's
//! charts ([`crate::chart`]) with the same code as the CLI's SVG files. Coordinates are CSS
//! pixels; the canvas' backing store is scaled by `devicePixelRatio` so lines stay sharp.
//! Text is measured by the context (`measureText`), at the SVG backend's font size
//! (`size / 1.24`), so the layout matches the SVG files'.

use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingBackend, DrawingErrorKind,
    FontTransform,
};
use web_sys::{CanvasRenderingContext2d, HtmlCanvasElement};

/// A canvas call that failed (the browser's message).
#[derive(Debug)]
pub struct CanvasError(pub String);

impl std::fmt::Display for CanvasError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "canvas: {}", self.0)
    }
}

impl std::error::Error for CanvasError {}

// The context and its error are only used on the (single-threaded) main thread of a page;
// plotters asks its backends' errors to be Send + Sync, which a String is.
fn js_err(e: wasm_bindgen::JsValue) -> DrawingErrorKind<CanvasError> {
    DrawingErrorKind::DrawingError(CanvasError(format!("{e:?}")))
}

/// The backend: a 2-D context and the drawing's size in CSS pixels.
pub struct CanvasBackend {
    ctx: CanvasRenderingContext2d,
    size: (u32, u32),
}

impl CanvasBackend {
    /// Sizes `canvas`'s backing store to its CSS box (`width` × `height` CSS pixels, times
    /// the device pixel ratio) and returns a backend drawing in CSS pixels.
    pub fn new(canvas: &HtmlCanvasElement, width: u32, height: u32) -> Result<Self, CanvasError> {
        let ratio = web_sys::window()
            .map_or(1.0, |w| w.device_pixel_ratio())
            .max(1.0);
        canvas.set_width((f64::from(width) * ratio).round() as u32);
        canvas.set_height((f64::from(height) * ratio).round() as u32);
        let ctx = canvas
            .get_context("2d")
            .map_err(|e| CanvasError(format!("{e:?}")))?
            .ok_or_else(|| CanvasError("the canvas has no 2-D context".into()))?;
        let ctx: CanvasRenderingContext2d = wasm_bindgen::JsCast::dyn_into(ctx)
            .map_err(|_| CanvasError("the 2-D context has an unexpected type".into()))?;
        ctx.set_transform(ratio, 0.0, 0.0, ratio, 0.0, 0.0)
            .map_err(|e| CanvasError(format!("{e:?}")))?;
        Ok(Self {
            ctx,
            size: (width, height),
        })
    }

    fn colour(c: BackendColor) -> String {
        let (r, g, b) = c.rgb;
        format!("rgba({r},{g},{b},{})", c.alpha)
    }

    fn stroke_style<S: BackendStyle>(&self, style: &S) {
        self.ctx.set_stroke_style_str(&Self::colour(style.color()));
        self.ctx.set_line_width(f64::from(style.stroke_width()));
    }

    fn font<S: BackendTextStyle>(&self, style: &S) {
        self.ctx.set_font(&format!(
            "{} {}px {}",
            style.style().as_str(),
            style.size() / 1.24,
            style.family().as_str()
        ));
    }

    /// A path through `points`, half-pixel aligned as the SVG files' strokes are.
    fn trace(&self, points: impl IntoIterator<Item = BackendCoord>) -> bool {
        self.ctx.begin_path();
        let mut any = false;
        for (k, (x, y)) in points.into_iter().enumerate() {
            let (x, y) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
            if k == 0 {
                self.ctx.move_to(x, y);
            } else {
                self.ctx.line_to(x, y);
            }
            any = true;
        }
        any
    }
}

impl DrawingBackend for CanvasBackend {
    type ErrorType = CanvasError;

    fn get_size(&self) -> (u32, u32) {
        self.size
    }

    fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<CanvasError>> {
        Ok(())
    }

    fn present(&mut self) -> Result<(), DrawingErrorKind<CanvasError>> {
        Ok(())
    }

    fn draw_pixel(
        &mut self,
        (x, y): BackendCoord,
        color: BackendColor,
    ) -> Result<(), DrawingErrorKind<CanvasError>> {
        self.ctx.set_fill_style_str(&Self::colour(color));
        self.ctx.fill_rect(f64::from(x), f64::from(y), 1.0, 1.0);
        Ok(())
    }

    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> Result<(), DrawingErrorKind<CanvasError>> {
        self.stroke_style(style);
        self.trace([from, to]);
        self.ctx.stroke();
        Ok(())
    }

    fn draw_rect<S: BackendStyle>(
        &mut self,
        (x0, y0): BackendCoord,
        (x1, y1): BackendCoord,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<CanvasError>> {
        let (x, y) = (f64::from(x0.min(x1)), f64::from(y0.min(y1)));
        let (w, h) = (f64::from((x1 - x0).abs()), f64::from((y1 - y0).abs()));
        if fill {
            self.ctx.set_fill_style_str(&Self::colour(style.color()));
            self.ctx.fill_rect(x, y, w + 1.0, h + 1.0);
        } else {
            self.stroke_style(style);
            self.ctx.stroke_rect(x + 0.5, y + 0.5, w, h);
        }
        Ok(())
    }

    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<CanvasError>> {
        self.stroke_style(style);
        self.ctx.set_line_join("round");
        if self.trace(path) {
            self.ctx.stroke();
        }
        Ok(())
    }

    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<CanvasError>> {
        self.ctx.set_fill_style_str(&Self::colour(style.color()));
        if self.trace(vert) {
            self.ctx.close_path();
            self.ctx.fill();
        }
        Ok(())
    }

    fn draw_circle<S: BackendStyle>(
        &mut self,
        (x, y): BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<CanvasError>> {
        self.ctx.begin_path();
        self.ctx
            .arc(
                f64::from(x),
                f64::from(y),
                f64::from(radius),
                0.0,
                std::f64::consts::TAU,
            )
            .map_err(js_err)?;
        if fill {
            self.ctx.set_fill_style_str(&Self::colour(style.color()));
            self.ctx.fill();
        } else {
            self.stroke_style(style);
            self.ctx.stroke();
        }
        Ok(())
    }

    fn estimate_text_size<S: BackendTextStyle>(
        &self,
        text: &str,
        style: &S,
    ) -> Result<(u32, u32), DrawingErrorKind<CanvasError>> {
        self.font(style);
        let width = self.ctx.measure_text(text).map_err(js_err)?.width();
        let height = style.size() / 1.24;
        Ok(match style.transform() {
            FontTransform::Rotate90 | FontTransform::Rotate270 => {
                (height.ceil() as u32, width.ceil() as u32)
            }
            _ => (width.ceil() as u32, height.ceil() as u32),
        })
    }

    fn draw_text<S: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &S,
        (x, y): BackendCoord,
    ) -> Result<(), DrawingErrorKind<CanvasError>> {
        let colour = style.color();
        if colour.alpha == 0.0 {
            return Ok(());
        }
        self.font(style);
        self.ctx.set_fill_style_str(&Self::colour(colour));
        self.ctx.set_text_align(match style.anchor().h_pos {
            HPos::Left => "left",
            HPos::Right => "right",
            HPos::Center => "center",
        });
        self.ctx.set_text_baseline(match style.anchor().v_pos {
            VPos::Top => "top",
            VPos::Center => "middle",
            VPos::Bottom => "bottom",
        });
        let angle: f64 = match style.transform() {
            FontTransform::None => 0.0,
            FontTransform::Rotate90 => 90.0,
            FontTransform::Rotate180 => 180.0,
            FontTransform::Rotate270 => 270.0,
        };
        self.ctx.save();
        self.ctx
            .translate(f64::from(x), f64::from(y))
            .map_err(js_err)?;
        self.ctx.rotate(angle.to_radians()).map_err(js_err)?;
        let drawn = self.ctx.fill_text(text, 0.0, 0.0).map_err(js_err);
        self.ctx.restore();
        drawn
    }
}
