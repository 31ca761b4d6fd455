//! `score --plot FILE.png`: the per-frame corner error and the status of
//! each frame over time, drawn with `plotters` into an RGB buffer and saved
//! as a PNG (through an [`OutputFile`]: a regular file appears only when
//! complete, a device or a named pipe is written in place). Text uses the
//! DejaVu Sans font built into the binary, so no system font is needed.

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::prelude::*;

use super::score::Score;
use crate::io::OutputFile;
use crate::io::formats::{FrameResult, Status};
use crate::{Error, Result};

/// Smallest and largest plot width, pixels (narrower, the legend covers
/// the curve and the status caption is cut).
pub const PLOT_WIDTH_RANGE: std::ops::RangeInclusive<usize> = 480..=8192;
/// Smallest and largest plot height, pixels (lower, the status strip is
/// squeezed out).
pub const PLOT_HEIGHT_RANGE: std::ops::RangeInclusive<usize> = 300..=8192;

/// Error unless `(w, h)` lies within [`PLOT_WIDTH_RANGE`] and [`PLOT_HEIGHT_RANGE`].
pub fn check_plot_size(w: usize, h: usize) -> std::result::Result<(), String> {
    let (width, height) = (PLOT_WIDTH_RANGE, PLOT_HEIGHT_RANGE);
    if width.contains(&w) && height.contains(&h) {
        return Ok(());
    }
    Err(format!(
        "plot size {w}x{h}: the width must be {} to {} pixels, the height {} to {}",
        width.start(),
        width.end(),
        height.start(),
        height.end()
    ))
}

/// Font family the plot's text is drawn in.
const FONT: &str = "sans-serif";

/// Status strip colours: tracking, tracking beyond the false-tracking threshold, lost.
const TRACKING: RGBColor = RGBColor(46, 160, 67);
const FALSE_TRACKING: RGBColor = RGBColor(230, 140, 0);
const LOST: RGBColor = RGBColor(210, 40, 40);

fn register_font() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        // The font is a valid TrueType file: registration cannot fail.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular());
    });
}

/// Draw `score`'s per-frame corner error (px, one line per run of scored
/// frames, with the false-tracking threshold) above a strip giving each
/// frame's status, `size` = (width, height) pixels, and save it at `path`.
/// A size [`check_plot_size`] refuses is an [`Error::Parameter`]; drawing or
/// writing errors name `path`.
pub fn plot_score(score: &Score, predictions: &[FrameResult], path: &Path, size: (usize, usize)) -> Result<()> {
    let (w, h) = size;
    check_plot_size(w, h).map_err(Error::Parameter)?;
    register_font();
    let mut pixels = vec![0u8; w * h * 3];
    draw(score, predictions, &mut pixels, (w as u32, h as u32))
        .map_err(|e| Error::input(path, format!("cannot draw the plot: {e}")))?;
    let mut png = Vec::new();
    ::image::ImageEncoder::write_image(
        ::image::codecs::png::PngEncoder::new(&mut png),
        &pixels,
        w as u32,
        h as u32,
        ::image::ExtendedColorType::Rgb8,
    )
    .map_err(|e| Error::input(path, format!("cannot encode the plot: {e}")))?;
    OutputFile::write_all_to(path, &png)
}

/// Check `--plot` before anything is read or written: it must be named
/// `.png`, and not be a folder nor one of `inputs` (the sequence's files and
/// the predictions), which the plot would overwrite. Errors name `path`.
pub fn check_plot_path(path: &Path, inputs: &[PathBuf]) -> Result<()> {
    if path.is_dir() {
        return Err(Error::input(path, "is a folder: --plot takes a file name"));
    }
    if let Some(input) = crate::io::Sequence::same_file_among(path, inputs) {
        return Err(Error::input(path, format!("is the input file {}: write the plot elsewhere", input.display())));
    }
    if !path.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
        return Err(Error::input(path, "the plot is a PNG image: name it .png"));
    }
    Ok(())
}

type DrawResult = std::result::Result<(), Box<dyn std::error::Error>>;

fn draw(score: &Score, predictions: &[FrameResult], pixels: &mut [u8], (w, h): (u32, u32)) -> DrawResult {
    let root = BitMapBackend::with_buffer(pixels, (w, h)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(h * 3 / 4);
    let frames = predictions.len().max(1) as f64;
    let font = |px: u32| (FONT, px as f64).into_font();

    // Corner error over time.
    let worst = score.stats.map_or(0.0, |s| s.max);
    let y_max = (worst.max(score.false_tracking_px) * 1.1).max(1.0);
    let mut chart = ChartBuilder::on(&top)
        .caption("corner error per frame", font(20))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..frames, 0.0..y_max)?;
    chart
        .configure_mesh()
        .x_desc("frame")
        .y_desc("corner error (px)")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .label_style(font(13))
        .axis_desc_style(font(14))
        .draw()?;
    let mut runs: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut last = None;
    for &(frame, error) in &score.frame_errors {
        if last.is_none_or(|l: usize| l + 1 != frame) {
            runs.push(Vec::new());
        }
        if let Some(run) = runs.last_mut() {
            run.push((frame as f64, error));
        }
        last = Some(frame);
    }
    for (i, run) in runs.into_iter().enumerate() {
        let series = chart.draw_series(LineSeries::new(run, BLUE.stroke_width(2)))?;
        if i == 0 {
            series.label("corner error").legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLUE.stroke_width(2)));
        }
    }
    let threshold = score.false_tracking_px;
    chart
        .draw_series(LineSeries::new([(0.0, threshold), (frames, threshold)], FALSE_TRACKING.stroke_width(1)))?
        .label(format!("false-tracking threshold ({threshold} px)"))
        .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], FALSE_TRACKING));
    chart.configure_series_labels().label_font(font(13)).background_style(WHITE.mix(0.8)).border_style(BLACK).draw()?;

    // Status of every frame.
    let mut strip = ChartBuilder::on(&bottom)
        .caption("status: green tracking, orange false tracking, red lost", font(15))
        .margin(10)
        .x_label_area_size(25)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..frames, 0.0..1.0)?;
    strip
        .configure_mesh()
        .disable_y_mesh()
        .disable_y_axis()
        .disable_x_mesh()
        .x_label_formatter(&|x| format!("{x:.0}"))
        .label_style(font(12))
        .draw()?;
    strip.draw_series(predictions.iter().map(|p| {
        let colour = match p.status {
            Status::Lost => LOST,
            _ if score.false_tracking.binary_search(&p.frame).is_ok() => FALSE_TRACKING,
            _ => TRACKING,
        };
        let x = p.frame as f64;
        Rectangle::new([(x, 0.0), (x + 1.0, 1.0)], colour.filled())
    }))?;
    root.present()?;
    Ok(())
}
