//! Reporting: progress, error metrics (per value, FLIP, the interior
//! mask), `diff` between images, error heat maps and error-vs-time charts.

pub mod chart;
pub mod convergence;
pub mod diff;
pub mod estimate;
pub mod flip;
pub mod heatmap;
pub mod interior;
pub mod metrics;
mod progress;

pub use chart::{
    error_vs_time_labels, pareto_front, place_labels, write_error_vs_time,
    write_error_vs_time_sized, ChartLabels, ChartPoint, LabelBox, LabelRequest, CHART_SIZE,
    MIN_CHART_SIZE,
};
pub use diff::{diff_images, ChannelDiff, DiffOptions, DiffReport};
pub use estimate::{SweepEstimate, Work};
pub use flip::{flip_radiance, flip_rgb8, FlipMap, FlipMetrics, FlipRegions, FLIP_PPD, FLIP_SCALE};
pub use heatmap::{
    colour_bar_rect, heatmap_canvas, heatmap_colour, write_error_heatmap, write_with_colour_bar,
    HeatmapScale, COLOUR_BAR_BAND, HEATMAP_BACKGROUND, HEATMAP_NON_FINITE, MIN_HEATMAP_WIDTH,
};
pub use interior::interior_mask;
pub use metrics::{error_metrics, ErrorAccumulator, ErrorMetrics, VISIBLE_ERROR};
pub use progress::{format_duration, Progress, RenderCost, MANY_SAMPLES};
