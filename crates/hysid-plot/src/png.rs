//! PNG figures: the SVG of a figure rasterised by `resvg` (pure Rust), its
//! text drawn with DejaVu Sans embedded in the program (Bitstream Vera
//! licence, `fonts/DejaVuSans-LICENSE.txt`), so the image is the same on
//! every machine and needs no system font. Built with the `png` feature
//! only (`cargo install --path crates/hysid-cli --features png`).

use crate::PlotError;

/// The file format figures are written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FigureFormat {
    /// Scalable vector graphics (the default; exact, small for line plots).
    #[default]
    Svg,
    /// A raster image at [`PNG_SCALE`] pixels per SVG unit, to paste.
    Png,
}

impl FigureFormat {
    /// Whether this build writes the format (PNG needs the `png` feature).
    pub fn is_built(self) -> bool {
        match self {
            FigureFormat::Svg => true,
            FigureFormat::Png => cfg!(feature = "png"),
        }
    }

    /// The format the extension of `path` names (`.svg`, `.png`), when this
    /// build writes it.
    pub fn of_path(path: &std::path::Path) -> Result<Self, PlotError> {
        let format = match path.extension().and_then(|e| e.to_str()) {
            Some("svg") => FigureFormat::Svg,
            Some("png") => FigureFormat::Png,
            _ => {
                return Err(PlotError::Format {
                    path: path.to_path_buf(),
                });
            }
        };
        if format.is_built() {
            Ok(format)
        } else {
            Err(PlotError::PngNotBuilt)
        }
    }

    /// The file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            FigureFormat::Svg => "svg",
            FigureFormat::Png => "png",
        }
    }
}

impl std::str::FromStr for FigureFormat {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "svg" => Ok(FigureFormat::Svg),
            "png" => Ok(FigureFormat::Png),
            other => Err(format!("'{other}' is not a figure format (svg or png)")),
        }
    }
}

/// The embedded font, registered as the `sans-serif` family the figures use.
#[cfg(feature = "png")]
const FONT: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");

/// Pixels per SVG unit: figures are drawn in SVG pixels and rasterised at
/// twice that, for sharp text on high-density screens and in documents.
pub const PNG_SCALE: f32 = 2.0;

/// The PNG image of the SVG document `svg`, at [`PNG_SCALE`].
#[cfg(feature = "png")]
pub fn svg_to_png(svg: &str) -> Result<Vec<u8>, PlotError> {
    let mut options = resvg::usvg::Options::default();
    let fonts = options.fontdb_mut();
    fonts.load_font_data(FONT.to_vec());
    fonts.set_sans_serif_family("DejaVu Sans");
    options.font_family = "DejaVu Sans".into();
    let tree = resvg::usvg::Tree::from_str(svg, &options)
        .map_err(|e| PlotError::Invalid(format!("the figure's SVG: {e}")))?;
    let size = tree
        .size()
        .to_int_size()
        .scale_by(PNG_SCALE)
        .ok_or_else(|| PlotError::Invalid("the figure is too large for a PNG image".into()))?;
    let mut pixmap = resvg::tiny_skia::Pixmap::new(size.width(), size.height())
        .ok_or_else(|| PlotError::Invalid("the figure has no area".into()))?;
    pixmap.fill(resvg::tiny_skia::Color::WHITE);
    resvg::render(
        &tree,
        resvg::tiny_skia::Transform::from_scale(PNG_SCALE, PNG_SCALE),
        &mut pixmap.as_mut(),
    );
    pixmap
        .encode_png()
        .map_err(|e| PlotError::Draw(format!("PNG encoding: {e}")))
}

/// Without the `png` feature: the error that says how to build it.
#[cfg(not(feature = "png"))]
pub fn svg_to_png(_svg: &str) -> Result<Vec<u8>, PlotError> {
    Err(PlotError::PngNotBuilt)
}
