//! Early vision: every stage exists twice, as a WGSL shader in `shaders/`
//! and as a CPU twin here, with the same parameters, the same clamp-to-edge
//! border policy and the same output layout. Each module holds one stage
//! `<stage>` (named like its shader): its parameters, its CPU twin
//! `<stage>_cpu` writing into caller-allocated outputs, the allocating
//! convenience `<stage>` over it, its GPU recording `encode`, and the
//! standalone `<stage>_gpu` (upload, run, read back) for tests and benches.

/// `fn $name(args) [-> ret]` that runs `$body(args)` compiled for AVX-512 or AVX2
/// where the CPU has them (std caches the detection) and for the baseline
/// target otherwise. The row loops of the twins vectorise either way; AVX2
/// doubles the lanes and AVX-512 doubles them again. Results are
/// bit-identical: the same IEEE operations in the same order, only wider
/// (Rust never contracts `a * b + c` into a fused multiply-add).
/// `$body` should be `#[inline(always)]` so it is compiled inside the AVX2
/// function.
macro_rules! simd_dispatch {
    ($(#[$m:meta])* fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? => $body:ident) => {
        $(#[$m])*
        fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl")]
                fn widest($($arg: $ty),*) $(-> $ret)? {
                    $body($($arg),*)
                }
                if std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512bw")
                    && std::arch::is_x86_feature_detected!("avx512dq")
                    && std::arch::is_x86_feature_detected!("avx512vl")
                {
                    // SAFETY: `widest` only needs these AVX-512 subsets, which the CPU was just found to have.
                    return unsafe { widest($($arg),*) };
                }
                #[target_feature(enable = "avx2")]
                fn wide($($arg: $ty),*) $(-> $ret)? {
                    $body($($arg),*)
                }
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: `wide` only needs AVX2, which the CPU was just found to have.
                    return unsafe { wide($($arg),*) };
                }
            }
            $body($($arg),*)
        }
    };
}

pub(crate) use simd_dispatch;

pub mod angle;
pub mod compaction;
pub mod cpf;
pub mod edge_pyramid;
pub mod frame_sum;
pub mod gaussian;
pub mod ingest;
pub mod log;
pub(crate) mod rows;
pub mod sobel;
pub mod temporal_diff;
pub mod window_energy;
pub mod zero_crossing;

/// Every shader the stages load, in the order a frame runs them; what
/// `tests/shader_validation.rs` checks against the WGSL with naga.
pub const SHADERS: &[crate::gpu::ShaderDef] = &[
    ingest::SHADER,
    ingest::TEXTURE_SHADER,
    gaussian::SHADER,
    temporal_diff::SHADER,
    frame_sum::SHADER,
    sobel::SHADER,
    log::SHADER,
    zero_crossing::SHADER,
    cpf::SHADER,
    edge_pyramid::SHADER,
    compaction::SHADER,
    window_energy::SHADER,
];

/// A rectangle of interest in pixel coordinates: columns `x0..x1`, rows
/// `y0..y1` (half-open). Empty when `x0 >= x1` or `y0 >= y1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Window {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

impl Window {
    /// The whole `width`×`height` image.
    #[must_use]
    pub fn full(width: usize, height: usize) -> Self {
        Self { x0: 0, y0: 0, x1: width as u32, y1: height as u32 }
    }

    /// The window around `points` (pixel coordinates, SPEC §4): the pixels
    /// whose centres lie within `margin` of the points' bounding box, widened
    /// outwards to whole pixels — columns ⌊x_min − margin⌋ up to and
    /// including ⌈x_max + margin⌉, rows likewise — clipped to a
    /// `width`×`height` image. With `margin` = ½ it holds every pixel a
    /// polygon with these vertices touches plus one pixel on each side.
    /// Points with a NaN coordinate are skipped (a vertex behind the camera
    /// has no image); an infinite coordinate reaches the image border.
    /// `None` when no point is left.
    #[must_use]
    pub fn around<'a>(
        points: impl IntoIterator<Item = &'a [f64; 2]>,
        margin: f64,
        width: usize,
        height: usize,
    ) -> Option<Self> {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        let mut any = false;
        for p in points.into_iter().filter(|p| !(p[0].is_nan() || p[1].is_nan())) {
            any = true;
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        if !any {
            return None;
        }
        let to = |v: f64, max: usize| v.clamp(0.0, max as f64) as u32;
        Some(Self {
            x0: to((lo[0] - margin).floor(), width),
            y0: to((lo[1] - margin).floor(), height),
            x1: to((hi[0] + margin).ceil() + 1.0, width),
            y1: to((hi[1] + margin).ceil() + 1.0, height),
        })
    }

    /// This window clipped to a `width`×`height` image.
    #[must_use]
    pub fn clipped(&self, width: usize, height: usize) -> Self {
        let (w, h) = (width as u32, height as u32);
        Self { x0: self.x0.min(w), y0: self.y0.min(h), x1: self.x1.min(w), y1: self.y1.min(h) }
    }

    /// The smallest window holding both (the other when one is empty).
    #[must_use]
    pub fn union(&self, other: &Self) -> Self {
        match (self.is_empty(), other.is_empty()) {
            (true, _) => *other,
            (_, true) => *self,
            _ => Self {
                x0: self.x0.min(other.x0),
                y0: self.y0.min(other.y0),
                x1: self.x1.max(other.x1),
                y1: self.y1.max(other.y1),
            },
        }
    }

    /// Whether every pixel of `other` lies in this window (an empty one
    /// lies in any).
    #[must_use]
    pub fn contains(&self, other: &Self) -> bool {
        other.is_empty() || (self.x0 <= other.x0 && self.y0 <= other.y0 && self.x1 >= other.x1 && self.y1 >= other.y1)
    }

    /// The window grown by `margin` pixels on every side (not clipped; an
    /// empty window stays empty).
    #[must_use]
    pub fn grown(&self, margin: u32) -> Self {
        if self.is_empty() {
            return *self;
        }
        Self {
            x0: self.x0.saturating_sub(margin),
            y0: self.y0.saturating_sub(margin),
            x1: self.x1.saturating_add(margin),
            y1: self.y1.saturating_add(margin),
        }
    }

    /// Width in pixels (0 when empty).
    #[must_use]
    pub fn width(&self) -> u32 {
        self.x1.saturating_sub(self.x0)
    }

    /// Height in pixels (0 when empty).
    #[must_use]
    pub fn height(&self) -> u32 {
        self.y1.saturating_sub(self.y0)
    }

    /// Number of pixels inside.
    #[must_use]
    pub fn area(&self) -> usize {
        self.width() as usize * self.height() as usize
    }

    /// True when the window holds no pixel.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.area() == 0
    }
}

/// One listed pixel: position, orientation θ (radians) and magnitude, as
/// produced by compaction. Layout matches the shader's `Feature` struct.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Feature {
    /// Column.
    pub x: u32,
    /// Row.
    pub y: u32,
    /// Orientation in radians (which orientation depends on the request).
    pub theta: f32,
    /// Magnitude (gradient or crossing strength).
    pub magnitude: f32,
}

#[cfg(test)]
mod window_tests {
    use super::Window;

    #[test]
    fn around_grows_the_bounding_box_by_the_margin_and_clips() {
        let points = [[10.2, 20.7], [30.5, 5.0], [f64::NAN, 1000.0]];
        // Columns ⌊10.2 − 2⌋ = 8 ..= ⌈30.5 + 2⌉ = 33; rows ⌊5 − 2⌋ = 3 ..= ⌈22.7⌉ = 23.
        assert_eq!(Window::around(&points, 2.0, 640, 480), Some(Window { x0: 8, y0: 3, x1: 34, y1: 24 }));
        assert_eq!(Window::around(&points, 2.0, 32, 10), Some(Window { x0: 8, y0: 3, x1: 32, y1: 10 }));
        assert_eq!(Window::around(&[[-4.0, 1.5]], 0.5, 640, 480), Some(Window { x0: 0, y0: 1, x1: 0, y1: 3 }));
        assert_eq!(Window::around(&[[f64::INFINITY, 1.0], [3.0, 1.0]], 0.0, 64, 48).map(|w| w.x1), Some(64));
        assert_eq!(Window::around(&[[f64::NAN, 1.0]], 1.0, 64, 48), None);
        assert_eq!(Window::around(&[], 1.0, 64, 48), None);
    }

    #[test]
    fn union_contains_and_grown_treat_empty_windows_as_nothing() {
        let a = Window { x0: 2, y0: 3, x1: 10, y1: 8 };
        let b = Window { x0: 6, y0: 1, x1: 12, y1: 5 };
        let empty = Window { x0: 50, y0: 50, x1: 50, y1: 60 };
        assert_eq!(a.union(&b), Window { x0: 2, y0: 1, x1: 12, y1: 8 });
        assert_eq!(a.union(&empty), a);
        assert_eq!(empty.union(&b), b);
        assert!(a.union(&b).contains(&a) && a.union(&b).contains(&b));
        assert!(!a.contains(&b) && a.contains(&empty) && !empty.contains(&a));
        assert_eq!(a.grown(2), Window { x0: 0, y0: 1, x1: 12, y1: 10 });
        assert_eq!(empty.grown(3), empty);
        assert_eq!(Window { x0: 0, y0: 0, x1: u32::MAX, y1: 1 }.grown(1).x1, u32::MAX);
    }
}
