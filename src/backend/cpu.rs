//! The CPU backend: the CPU twins of every stage, with buffers reused from
//! frame to frame so the per-frame loop does not allocate images.

use super::{EarlyVision, FrameFeatures, FrameRequest, Pyramids};
use crate::Result;
use crate::early::Feature;
use crate::early::compaction::compaction_cpu;
use crate::early::gaussian::gaussian_cpu;
use crate::early::ingest::ingest_cpu;
use crate::early::log::log_cpu;
use crate::early::sobel::{SobelOutput, sobel_cpu};
use crate::early::temporal_diff;
use crate::early::zero_crossing::{Edgels, zero_crossing_cpu};
use crate::early::{cpf, edge_pyramid};
use crate::image::{FloatImage, GrayImage};

/// Early vision on the CPU (rayon threads across rows for large frames).
#[derive(Debug)]
pub struct CpuBackend {
    luma: FloatImage,
    tmp: FloatImage,
    tmp2: FloatImage,
    smoothed: FloatImage,
    previous: Option<FloatImage>,
    motion_mask: FloatImage,
    sum: FloatImage,
    sobel_sum: SobelOutput,
    sobel_edges: SobelOutput,
    log: FloatImage,
    edgels: Edgels,
    /// Lists and pyramids handed back by [`EarlyVision::recycle`], refilled
    /// by the next frame (no per-frame allocation, no copy of the levels).
    spare: FrameFeatures,
}

impl Default for CpuBackend {
    fn default() -> Self {
        Self::new()
    }
}

impl CpuBackend {
    /// A CPU backend with empty buffers (they grow on the first frame).
    #[must_use]
    pub fn new() -> Self {
        Self {
            luma: FloatImage::new(0, 0),
            tmp: FloatImage::new(0, 0),
            tmp2: FloatImage::new(0, 0),
            smoothed: FloatImage::new(0, 0),
            previous: None,
            motion_mask: FloatImage::new(0, 0),
            sum: FloatImage::new(0, 0),
            sobel_sum: SobelOutput::new(0, 0),
            sobel_edges: SobelOutput::new(0, 0),
            log: FloatImage::new(0, 0),
            edgels: Edgels::new(0, 0),
            spare: FrameFeatures::default(),
        }
    }
}

impl EarlyVision for CpuBackend {
    fn name(&self) -> String {
        format!("CPU ({} threads)", rayon::current_num_threads())
    }

    fn reset(&mut self) {
        self.previous = None;
    }

    fn recycle(&mut self, features: FrameFeatures) {
        self.spare = features;
    }

    fn process(&mut self, frame: &GrayImage, request: &FrameRequest) -> Result<FrameFeatures> {
        let mut out = FrameFeatures::default();
        // An empty list (reusing a recycled allocation when there is one).
        fn list_from(spare: &mut Option<Vec<Feature>>) -> Vec<Feature> {
            let mut list = spare.take().unwrap_or_default();
            list.clear();
            list
        }
        if self.previous.as_ref().is_some_and(|p| p.size() != frame.size()) {
            self.previous = None;
        }
        ingest_cpu(frame, &mut self.luma);
        if request.needs_smoothing() {
            gaussian_cpu(&self.luma, &request.smoothing, &mut self.tmp, &mut self.smoothed)?;
        }

        if let Some(m) = &request.motion {
            let mut list = list_from(&mut self.spare.motion);
            if let Some(prev) = &self.previous {
                // 000 eq. 1: G*_t − G*_{t+1}, thresholded; eq. 2 on the sum of both.
                // Fused: one pass over both frames writes the mask and the sum.
                temporal_diff::temporal_diff_and_sum_cpu(
                    prev,
                    &self.smoothed,
                    &m.diff,
                    &mut self.motion_mask,
                    &mut self.sum,
                )?;
                sobel_cpu(&self.sum, &mut self.sobel_sum);
                compaction_cpu(
                    &self.motion_mask,
                    &self.sobel_sum.theta,
                    &self.sobel_sum.magnitude,
                    &m.list.compaction(0.5),
                    &mut list,
                )?;
            }
            out.motion = Some(list);
        }

        if let Some(e) = &request.edges {
            let src = if e.smoothed { &self.smoothed } else { &self.luma };
            sobel_cpu(src, &mut self.sobel_edges);
            let mut list = list_from(&mut self.spare.edges);
            let s = &self.sobel_edges;
            compaction_cpu(&s.magnitude, &s.direction, &s.magnitude, &e.list.compaction(e.threshold), &mut list)?;
            out.edges = Some(list);
        }

        if let Some(z) = &request.zero_crossings {
            log_cpu(&self.luma, &z.log, &mut self.tmp, &mut self.tmp2, &mut self.log)?;
            zero_crossing_cpu(&self.log, &z.crossings, &mut self.edgels);
            let mut list = list_from(&mut self.spare.zero_crossings);
            let ed = &self.edgels;
            compaction_cpu(&ed.strength, &ed.direction, &ed.strength, &z.list.compaction(0.0), &mut list)?;
            out.zero_crossings = Some(list);
        }

        if request.builds_pyramids() {
            // Computed straight into the levels handed out (recycled ones
            // when the caller gave them back): no copy of every level.
            let (mut cpf_levels, mut edge_levels) = self.spare.pyramids.take().unwrap_or_default();
            cpf::cpf_cpu(&self.luma, &mut cpf_levels);
            if request.edges.is_none() || request.edges.is_some_and(|e| e.smoothed) {
                sobel_cpu(&self.luma, &mut self.sobel_edges);
            }
            edge_pyramid::edge_pyramid_cpu(&self.sobel_edges.gx, &self.sobel_edges.gy, &mut edge_levels)?;
            if request.pyramids == Pyramids::Return {
                out.pyramids = Some((cpf_levels, edge_levels));
            } else {
                self.spare.pyramids = Some((cpf_levels, edge_levels));
            }
        }

        if request.motion.is_some() {
            // Keep this frame's smoothed image as the next frame's "previous".
            match &mut self.previous {
                Some(p) => std::mem::swap(p, &mut self.smoothed),
                None => self.previous = Some(self.smoothed.clone()),
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testimage::natural;

    /// Recycled lists and pyramid levels are refilled, not appended to: a
    /// backend fed its own features back answers as one that is not.
    #[test]
    fn recycling_features_changes_nothing() {
        let (w, h) = (40, 30);
        let base = natural(w + 3, h, 7);
        let frames: Vec<GrayImage> = (0..3).map(|k| GrayImage::from_fn(w, h, |x, y| base.get(x + k, y))).collect();
        let request = FrameRequest::full_chain(w, h);
        let (mut fresh, mut recycling) = (CpuBackend::new(), CpuBackend::new());
        for f in &frames {
            let expected = fresh.process(f, &request).unwrap();
            let got = recycling.process(f, &request).unwrap();
            assert_eq!(got, expected);
            recycling.recycle(got);
        }
    }
}
