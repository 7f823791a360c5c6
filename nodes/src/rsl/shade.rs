//! Per-vertex shading with square lights (Xu et al. 2006 Eq. 5).
