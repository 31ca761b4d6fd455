//! Image buffers that know their size.

use crate::{Error, Result};

/// A row-major single-channel image of `T` (pixel `(x, y)` at `data[y * width + x]`).
#[derive(Clone, Debug, PartialEq)]
pub struct Image<T> {
    width: usize,
    height: usize,
    data: Vec<T>,
}

impl<T: Copy + Default> Image<T> {
    /// A `width`×`height` image filled with `T::default()`.
    #[must_use]
    pub fn new(width: usize, height: usize) -> Self {
        Self { width, height, data: vec![T::default(); width * height] }
    }

    /// Wrap `data` (row-major) as a `width`×`height` image.
    pub fn from_vec(width: usize, height: usize, data: Vec<T>) -> Result<Self> {
        if data.len() != width * height {
            return Err(Error::Size(format!("{} values for a {width}x{height} image", data.len())));
        }
        Ok(Self { width, height, data })
    }

    /// Build an image by evaluating `f(x, y)` at every pixel.
    #[must_use]
    pub fn from_fn(width: usize, height: usize, mut f: impl FnMut(usize, usize) -> T) -> Self {
        let mut data = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                data.push(f(x, y));
            }
        }
        Self { width, height, data }
    }

    /// Width in pixels.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// `(width, height)`.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The pixels, row-major.
    #[must_use]
    pub fn data(&self) -> &[T] {
        &self.data
    }

    /// The pixels, row-major, mutable.
    pub fn data_mut(&mut self) -> &mut [T] {
        &mut self.data
    }

    /// Consume the image, returning its pixels.
    #[must_use]
    pub fn into_vec(self) -> Vec<T> {
        self.data
    }

    /// Pixel `(x, y)`; panics when out of bounds (internal use with checked indices).
    #[must_use]
    pub fn get(&self, x: usize, y: usize) -> T {
        self.data[y * self.width + x]
    }

    /// Pixel at `(x, y)` with coordinates clamped to the image (clamp-to-edge border).
    #[must_use]
    pub fn get_clamped(&self, x: isize, y: isize) -> T {
        let x = x.clamp(0, self.width as isize - 1) as usize;
        let y = y.clamp(0, self.height as isize - 1) as usize;
        self.data[y * self.width + x]
    }

    /// Set pixel `(x, y)`.
    pub fn set(&mut self, x: usize, y: usize, v: T) {
        self.data[y * self.width + x] = v;
    }

    /// Row `y` as a slice.
    #[must_use]
    pub fn row(&self, y: usize) -> &[T] {
        &self.data[y * self.width..(y + 1) * self.width]
    }

    /// Resize to `width`×`height`, reusing the allocation (contents unspecified).
    pub fn resize(&mut self, width: usize, height: usize) {
        self.width = width;
        self.height = height;
        self.data.resize(width * height, T::default());
    }

    /// Error unless `other` has the same size as `self`.
    pub fn check_same_size<U>(&self, other: &Image<U>, what: &str) -> Result<()> {
        if (self.width, self.height) != (other.width, other.height) {
            return Err(Error::Size(format!(
                "{what}: {}x{} vs {}x{}",
                self.width, self.height, other.width, other.height
            )));
        }
        Ok(())
    }
}

/// An 8-bit grey frame.
pub type GrayImage = Image<u8>;
/// A 32-bit float image (intensities stay in the 0..255 scale of the input).
pub type FloatImage = Image<f32>;
/// An 8-bit RGB colour frame, one `[r, g, b]` per pixel.
pub type RgbImage = Image<[u8; 3]>;

impl RgbImage {
    /// The grey frame of this colour frame, through [`luma`]: the same bytes
    /// a colour file decodes to when read as grey.
    #[must_use]
    pub fn to_gray(&self) -> GrayImage {
        Image {
            width: self.width,
            height: self.height,
            data: self.data.iter().map(|&[r, g, b]| luma(r, g, b)).collect(),
        }
    }

    /// A colour frame whose three channels all equal `gray`.
    #[must_use]
    pub fn from_gray(gray: &GrayImage) -> Self {
        Image { width: gray.width, height: gray.height, data: gray.data.iter().map(|&v| [v, v, v]).collect() }
    }
}

impl GrayImage {
    /// Convert to f32 (0..255 scale), the CPU twin of the `ingest` shader.
    #[must_use]
    pub fn to_f32(&self) -> FloatImage {
        Image { width: self.width, height: self.height, data: self.data.iter().map(|&v| v as f32).collect() }
    }
}

/// BT.601 luma of 8-bit R, G, B rounded to the nearest integer, halves up,
/// in exact integer arithmetic: `(299 r + 587 g + 114 b + 500) / 1000`. Colour
/// frames read from files and colour textures (the `ingest_texture` shader)
/// both become grey through it, so the two paths agree to the bit.
#[must_use]
pub const fn luma(r: u8, g: u8, b: u8) -> u8 {
    let sum = LUMA_WEIGHTS[0] * r as u32 + LUMA_WEIGHTS[1] * g as u32 + LUMA_WEIGHTS[2] * b as u32;
    ((sum + LUMA_SCALE / 2) / LUMA_SCALE) as u8
}

/// BT.601 weights of R, G, B in thousandths (they sum to [`LUMA_SCALE`]).
const LUMA_WEIGHTS: [u32; 3] = [299, 587, 114];
/// Denominator of [`LUMA_WEIGHTS`].
const LUMA_SCALE: u32 = 1000;
