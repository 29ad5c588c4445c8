//! The time left of a `compare` sweep, from the costs measured so far.
//!
//! A sweep's pieces of work (each scene's reference, then its runs) differ
//! in cost by a hundredfold and more: 4 against 256 light samples, a
//! rasteriser against a ray tracer, a fixed setup (geometry, G-buffer,
//! acceleration structures) that can outweigh the samples at a small
//! image. An estimate from equal steps (what a progress bar's own rate
//! gives) is then off by as much, in either direction; so is a static
//! guess of relative costs. [`SweepEstimate`] instead models one render of
//! a technique curve as `a + b × samples` seconds and predicts each piece
//! not yet done from the pieces already timed, most specific first:
//!
//! 1. the same curve on the same scene at two or more sample counts: the
//!    line fitted to them (least squares, `a, b >= 0`);
//! 2. the same curve on the same scene at one sample count: that time,
//!    with the slope `b` of its cost class ([`Work::per_sample`]) from the
//!    other curves' lines (a ray tracer's from the reference, whose
//!    samples dominate it; a class without one: another class's, scaled
//!    by the classes' per-sample costs);
//! 3. the same curve on another scene: that scene's prediction scaled by
//!    the pixels;
//! 4. a curve not timed yet: the cheapest render timed so far as its
//!    fixed part `a` (before any run, a render without shadows of the
//!    scene: [`SweepEstimate::baseline`]) and its class's slope.
//!
//! A ray tracer timed at one sample count where its samples dominate (the
//! reference) gives its class's slope as its time above that fixed part
//! per sample. Until every piece has a prediction by these rules there
//! is no estimate (a static guess of relative costs was off by 40× in
//! the first seconds of a sweep): the bar says it is estimating. The runs
//! of a sweep are made round robin over the curves (`compare`'s
//! execution order), so every curve is timed early, before its dearest
//! runs.
//!
//! A scene's reference is a piece of the curve `reference` (two renders
//! at half the reference's samples: the same ray tracer as the
//! `reference` technique's runs), so the technique's runs are predicted
//! from it; a reference read from the cache predicts with the time its
//! computation took (the cache records it), not the time the read took.
//! The piece under way may report how far it is ([`SweepEstimate::part`],
//! e.g. a reference's first half) or what probe renders expect of it
//! ([`SweepEstimate::expect`]): it then predicts itself, and the others,
//! by that.
//!
//! Pure: every time is given in seconds since the sweep started, so the
//! estimate is a function of what was measured, testable without a clock.

/// One piece of a sweep's work, as known before it runs.
#[derive(Debug, Clone, PartialEq)]
pub struct Work {
    /// Index of its scene in the sweep.
    pub scene: usize,
    /// Index of the run among the scene's runs; `None` for the scene's
    /// reference.
    pub run: Option<usize>,
    /// The technique curve (runs of one curve scale with each other).
    pub curve: String,
    /// Light samples per render (`None`: the technique takes none).
    pub samples: Option<u32>,
    /// Renders it makes (`--repeat` for a run; 2 halves for a reference).
    pub renders: u32,
    /// Pixels per render.
    pub pixels: u64,
    /// Its technique's relative cost of a light sample (the cost class's
    /// [`crate::shadow::technique::CostClass::per_sample`]): curves of a
    /// class share a slope until their own is measured.
    pub per_sample: u64,
}

impl Work {
    fn samples(&self) -> f64 {
        f64::from(self.samples.unwrap_or(0))
    }

    fn renders(&self) -> f64 {
        f64::from(self.renders.max(1))
    }
}

/// Measured and predicted time of a sweep's work.
#[derive(Debug, Clone)]
pub struct SweepEstimate {
    work: Vec<Work>,
    /// Per piece once done: (wall seconds it took, seconds to predict
    /// other pieces with).
    done: Vec<Option<(f64, f64)>>,
    /// The piece under way, when it started, and how far it was when
    /// last reported (when, and the share done).
    current: Option<Current>,
    /// The seconds the piece under way is expected to take, from probes
    /// ([`SweepEstimate::expect`]), until it reports a share.
    expected: Option<f64>,
    /// Per scene, seconds of a render without shadows.
    baselines: Vec<(usize, f64)>,
    /// Pieces known before they run to be read from a cache, with the
    /// seconds their computation took.
    cached: Vec<(usize, f64)>,
}

/// The piece under way: its index, when it started, and when it last
/// reported a share done and that share.
type Current = (usize, f64, Option<(f64, f64)>);

/// One timed piece: its work and seconds per render.
type Timed<'a> = (&'a Work, f64);

/// What the pieces timed so far tell: the pieces with their seconds per
/// render, and the cheapest render (the fixed part of a render of a
/// curve not timed yet) at a number of pixels.
struct Known<'a> {
    timed: Vec<Timed<'a>>,
    /// Seconds of the cheapest render and its pixels.
    fixed: Option<(f64, u64)>,
}

impl Known<'_> {
    /// The fixed part of a render of `pixels` pixels.
    fn fixed(&self, pixels: u64) -> Option<f64> {
        self.fixed
            .map(|(seconds, at)| seconds * pixels as f64 / at.max(1) as f64)
    }
}

impl SweepEstimate {
    /// An estimate of `work`, nothing done yet.
    pub fn new(work: Vec<Work>) -> Self {
        let done = vec![None; work.len()];
        SweepEstimate {
            work,
            done,
            current: None,
            expected: None,
            baselines: Vec::new(),
            cached: Vec::new(),
        }
    }

    /// The pieces, in order.
    pub fn work(&self) -> &[Work] {
        &self.work
    }

    /// The index of the piece of `scene` (`run`; `None` for its
    /// reference), if it is part of the work.
    pub fn index_of(&self, scene: usize, run: Option<usize>) -> Option<usize> {
        self.work
            .iter()
            .position(|w| w.scene == scene && w.run == run)
    }

    /// Piece `i` starts at `at`.
    pub fn start(&mut self, i: usize, at: f64) {
        if i < self.work.len() {
            self.current = Some((i, at, None));
            self.expected = None;
        }
    }

    /// The piece under way is expected to take `seconds` in all (from
    /// probe renders): it is predicted so, and predicts the others so,
    /// until it reports a share of its own ([`SweepEstimate::part`]).
    pub fn expect(&mut self, seconds: f64) {
        if self.current.is_some() && seconds.is_finite() && seconds > 0.0 {
            self.expected = Some(seconds);
        }
    }

    /// Piece `i` will be read from a cache (quick: predicted as no time),
    /// and its computation took `seconds`: it predicts the others so
    /// from now on, as it will once done ([`SweepEstimate::finish`] with
    /// a model).
    pub fn cached(&mut self, i: usize, seconds: f64) {
        if i < self.work.len() && seconds.is_finite() && seconds >= 0.0 {
            self.cached.retain(|(c, _)| *c != i);
            self.cached.push((i, seconds));
        }
    }

    /// A render of `scene` without shadows takes `seconds`: before any
    /// run is timed, the fixed part of the scene's renders.
    pub fn baseline(&mut self, scene: usize, seconds: f64) {
        if seconds.is_finite() && seconds >= 0.0 {
            self.baselines.retain(|(s, _)| *s != scene);
            self.baselines.push((scene, seconds));
        }
    }

    /// The piece under way is `share` (in (0, 1)) done at `at`.
    pub fn part(&mut self, at: f64, share: f64) {
        if let Some((_, started, progress)) = &mut self.current {
            if share > 0.0 && share < 1.0 && at > *started {
                *progress = Some((at, share));
            }
        }
    }

    /// Piece `i` ends at `at`; with `model`, other pieces are predicted
    /// from that time instead of the time it took (a cached reference:
    /// the time its computation took).
    pub fn finish(&mut self, i: usize, at: f64, model: Option<f64>) {
        let Some(slot) = self.done.get_mut(i) else {
            return;
        };
        let started = match self.current {
            Some((c, s, _)) if c == i => s,
            _ => at,
        };
        let took = (at - started).max(0.0);
        *slot = Some((took, model.unwrap_or(took).max(0.0)));
        if self.current.is_some_and(|(c, _, _)| c == i) {
            self.current = None;
        }
    }

    /// Pieces done.
    pub fn done(&self) -> usize {
        self.done.iter().filter(|d| d.is_some()).count()
    }

    /// What is known: the pieces timed (done, or under way with a share
    /// reported) with their seconds per render, and the cheapest render:
    /// a run's, else a render without shadows.
    fn known(&self) -> Known<'_> {
        let mut timed: Vec<Timed> = (self.work.iter().zip(&self.done))
            .filter_map(|(w, d)| d.map(|(_, model)| (w, model / w.renders())))
            .collect();
        for &(i, seconds) in &self.cached {
            if self.done[i].is_none() {
                let w = &self.work[i];
                timed.push((w, seconds / w.renders()));
            }
        }
        if let Some(total) = self.current_total() {
            if let Some((i, ..)) = self.current {
                let w = &self.work[i];
                timed.push((w, total / w.renders()));
            }
        }
        let per_pixel = |(seconds, pixels): (f64, u64)| seconds / pixels.max(1) as f64;
        let cheapest = |found: Vec<(f64, u64)>| {
            found
                .into_iter()
                .min_by(|a, b| per_pixel(*a).total_cmp(&per_pixel(*b)))
        };
        let runs = (timed.iter())
            .filter(|(m, _)| m.run.is_some())
            .map(|(m, r)| (*r, m.pixels))
            .collect();
        let baselines = (self.baselines.iter())
            .filter_map(|&(scene, seconds)| {
                let w = self.work.iter().find(|w| w.scene == scene)?;
                Some((seconds, w.pixels))
            })
            .collect();
        let fixed = cheapest(runs).or_else(|| cheapest(baselines));
        Known { timed, fixed }
    }

    /// Predicted seconds of piece `i` from the pieces timed (its measured
    /// time once done); `None` before anything usable is measured.
    pub fn predicted(&self, i: usize) -> Option<f64> {
        if let Some(Some((took, _))) = self.done.get(i) {
            return Some(*took);
        }
        let w = self.work.get(i)?;
        if self.current.is_some_and(|(c, ..)| c == i) {
            if let Some(total) = self.current_total() {
                return Some(total);
            }
        }
        if self.cached.iter().any(|(c, _)| *c == i) {
            return Some(0.0);
        }
        per_render(w, &self.known()).map(|r| r * w.renders())
    }

    /// The whole time of the piece under way, by its own pace (a share
    /// reported) or its probes' expectation.
    fn current_total(&self) -> Option<f64> {
        match self.current? {
            (_, started, Some((at, share))) => Some((at - started) / share),
            _ => self.expected,
        }
    }

    /// Seconds left at `at` (seconds since the sweep started): every
    /// piece not done, the one under way less the time it has had (never
    /// below zero). `None` before anything usable is measured.
    pub fn left(&self, at: f64) -> Option<f64> {
        let mut left = 0.0;
        for i in 0..self.work.len() {
            if self.done[i].is_some() {
                continue;
            }
            let p = self.predicted(i)?;
            left += match self.current {
                Some((c, started, _)) if c == i => (p - (at - started)).max(0.0),
                _ => p,
            };
        }
        Some(left)
    }

    /// The share of the sweep done at `at`, by time: elapsed over elapsed
    /// plus left; `None` while [`Self::left`] is.
    pub fn fraction(&self, at: f64) -> Option<f64> {
        let left = self.left(at)?;
        let at = at.max(0.0);
        Some(match at + left {
            t if t > 0.0 => at / t,
            _ => 1.0,
        })
    }
}

/// Seconds per render of `w` from what is `known` (see the module docs
/// for the order of the rules).
fn per_render(w: &Work, known: &Known) -> Option<f64> {
    let timed = &known.timed;
    let points: Vec<(f64, f64)> = (timed.iter())
        .filter(|(m, _)| m.scene == w.scene && m.curve == w.curve)
        .map(|(m, r)| (m.samples(), *r))
        .collect();
    // 1: the curve's own line.
    if let Some((a, b)) = fit_line(&points) {
        return Some(a + b * w.samples());
    }
    let slope = class_slope(w.per_sample, known);
    // 2: one sample count of the curve, the class's slope.
    if !points.is_empty() {
        let n = points.len() as f64;
        let (s, r) = points
            .iter()
            .fold((0.0, 0.0), |(s, r), p| (s + p.0 / n, r + p.1 / n));
        return match slope {
            Some(b) => Some((r - b * s).max(0.0) + b * w.samples()),
            // No slope known anywhere: only the same sample count.
            None => (w.samples() == s).then_some(r),
        };
    }
    // 3: the curve on another scene, scaled by the pixels.
    let other = (timed.iter())
        .find(|(m, _)| m.curve == w.curve && m.scene != w.scene)
        .map(|(m, _)| m);
    if let Some(m) = other {
        let elsewhere = Work {
            scene: m.scene,
            ..w.clone()
        };
        let scale = w.pixels as f64 / m.pixels.max(1) as f64;
        return per_render(&elsewhere, known).map(|r| r * scale);
    }
    // 4: a new curve: the cheapest render as its fixed part, its class's
    // slope.
    Some(known.fixed(w.pixels)? + slope? * w.samples())
}

/// Seconds per render and light sample of a curve of cost class
/// `per_sample`, from what is `known`: the median slope of the class's
/// curves with a line; else, for a ray tracer timed at one sample count
/// (the reference: its samples dominate it), its time above the fixed
/// part per sample; else another class's, scaled by the classes'
/// per-sample costs. `None` when nothing gives one; 0 for a class whose
/// samples cost nothing.
fn class_slope(per_sample: u64, known: &Known) -> Option<f64> {
    if per_sample == 0 {
        return Some(0.0);
    }
    // Every curve's points, by scene and curve.
    let mut curves: Vec<(&Work, Vec<(f64, f64)>)> = Vec::new();
    for (m, r) in &known.timed {
        match curves
            .iter_mut()
            .find(|(c, _)| c.scene == m.scene && c.curve == m.curve)
        {
            Some((_, points)) => points.push((m.samples(), *r)),
            None => curves.push((m, vec![(m.samples(), *r)])),
        }
    }
    let slope_of = |class: u64| -> Option<f64> {
        let mut slopes: Vec<f64> = (curves.iter())
            .filter(|(c, _)| c.per_sample == class)
            .filter_map(|(_, p)| fit_line(p).map(|(_, b)| b))
            .collect();
        if slopes.is_empty() && class >= RAY_TRACED {
            // Only where the samples are most of the time: a few samples
            // say nothing of what more cost.
            slopes = (curves.iter())
                .filter(|(c, p)| c.per_sample == class && p[0].0 > 0.0)
                .filter_map(|(c, p)| {
                    let (s, r) = p[0];
                    let fixed = known.fixed(c.pixels)?;
                    (r - fixed >= r / 2.0).then(|| (r - fixed) / s)
                })
                .collect();
        }
        slopes.sort_by(f64::total_cmp);
        slopes.get(slopes.len() / 2).copied()
    };
    if let Some(b) = slope_of(per_sample) {
        return Some(b);
    }
    let mut classes: Vec<u64> = curves.iter().map(|(c, _)| c.per_sample).collect();
    classes.sort_unstable();
    classes.dedup();
    classes
        .into_iter()
        .filter(|&c| c > 0 && c != per_sample)
        .find_map(|c| slope_of(c).map(|b| b * per_sample as f64 / c as f64))
}

/// The per-sample cost of the ray-traced class (`CostClass::Rays`):
/// classes at least this dear are ray tracers, whose samples dominate a
/// render.
const RAY_TRACED: u64 = 8;

/// The least-squares line `y = a + b x` through `points` with `a, b >= 0`
/// (a negative part is dropped and the other refitted); `None` unless
/// there are two distinct `x`.
fn fit_line(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    let n = points.len() as f64;
    let first = points.first()?.0;
    if !points.iter().any(|p| p.0 != first) {
        return None;
    }
    let (sx, sy) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), p| (a + p.0, b + p.1));
    let (mx, my) = (sx / n, sy / n);
    let (sxx, sxy) = points.iter().fold((0.0, 0.0), |(a, b), p| {
        (a + (p.0 - mx).powi(2), b + (p.0 - mx) * (p.1 - my))
    });
    let b = sxy / sxx;
    let a = my - b * mx;
    if b < 0.0 {
        // Time that does not grow with the samples: their mean.
        return Some((my.max(0.0), 0.0));
    }
    if a < 0.0 {
        // Through the origin.
        let (xx, xy) = points
            .iter()
            .fold((0.0, 0.0), |(a, b), p| (a + p.0 * p.0, b + p.0 * p.1));
        return Some((0.0, (xy / xx).max(0.0)));
    }
    Some((a, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    const PIXELS: u64 = 1000;

    fn work(run: Option<usize>, curve: &str, samples: u32) -> Work {
        // The cost classes' per-sample costs: rays 8, rasterised 1.
        let per_sample = if curve == "reference" { 8 } else { 1 };
        let renders = if run.is_some() { 3 } else { 2 };
        Work {
            scene: 0,
            run,
            curve: curve.into(),
            samples: Some(samples),
            renders,
            pixels: PIXELS,
            per_sample,
        }
    }

    /// A sweep like `compare`'s default on one scene: the reference (two
    /// halves of 512 samples), then three techniques at 4, 16, 64 and 256
    /// samples, whose true times per render follow `a + b × samples`
    /// with costs far from the static guess: DCS's samples nearly free,
    /// penumbra casting dear and with a large fixed part, and a fixed
    /// setup that outweighs the samples at a small image.
    fn sweep() -> (Vec<Work>, Vec<f64>) {
        let model = [
            ("dcs", 0.25, 0.0003),
            ("penumbra-casting", 0.6, 0.005),
            ("reference", 0.2, 0.0015),
        ];
        let mut work = vec![work(None, "reference", 512)];
        let mut truth = vec![2.0 * (0.2 + 0.0015 * 512.0)];
        for (curve, a, b) in model {
            for n in [4u32, 16, 64, 256] {
                let i = work.len() - 1;
                work.push(self::work(Some(i), curve, n));
                truth.push(3.0 * (a + b * f64::from(n)));
            }
        }
        (work, truth)
    }

    #[test]
    fn nothing_measured_gives_no_estimate() {
        let (work, _) = sweep();
        let e = SweepEstimate::new(work);
        assert_eq!(e.left(0.0), None);
        assert_eq!(e.fraction(0.0), None);
        assert_eq!(e.done(), 0);
    }

    /// Feeds the sweep's true times in `compare`'s order (the reference,
    /// then round robin over the curves), after a render without shadows
    /// of a third of the cheapest run's: once every curve has been timed
    /// (a quarter of the way in, here) the time left is within 2× of the
    /// truth (before, an untimed technique's cost is a guess), and once
    /// a curve has two sample counts its line predicts the rest of it
    /// exactly.
    #[test]
    fn the_estimate_follows_measured_costs() {
        let (work, truth) = sweep();
        let total: f64 = truth.iter().sum();
        let order: Vec<usize> = std::iter::once(0)
            .chain((0..4).flat_map(|round| (0..3).map(move |curve| 1 + curve * 4 + round)))
            .collect();
        let mut e = SweepEstimate::new(work.clone());
        e.baseline(0, 0.08);
        let (mut at, mut checked) = (0.0, 0);
        for (k, &i) in order.iter().enumerate() {
            e.start(i, at);
            let t = truth[i];
            // A reference reports its first half.
            if work[i].run.is_none() {
                e.part(at + t / 2.0, 0.5);
            }
            // Halfway through the piece: the time left counts its rest.
            let left = e.left(at + t / 2.0).expect("an estimate");
            let actual = total - at - t / 2.0;
            if k > 3 {
                assert!(
                    left <= 2.0 * actual && actual <= 2.0 * left,
                    "piece {i} at {at} s of {total}: {left} s left estimated, {actual} s actual"
                );
                checked += 1;
            }
            at += t;
            e.finish(i, at, None);
            let took = e.predicted(i).unwrap_or(f64::NAN);
            assert!((took - t).abs() < 1e-9 * total, "{took} vs {t}");
            // Two sample counts of a curve (the reference's own piece
            // counts for the reference's): the rest of it, exactly.
            let curve = &work[i].curve;
            let timed = order[..=k]
                .iter()
                .filter(|&&j| work[j].curve == *curve)
                .count();
            if timed >= 2 {
                for j in (0..work.len()).filter(|&j| work[j].curve == *curve) {
                    let p = e.predicted(j).unwrap_or(f64::NAN);
                    assert!(
                        (p - truth[j]).abs() < 1e-6 * truth[j],
                        "piece {j}: {p} vs {}",
                        truth[j]
                    );
                }
            }
        }
        assert!(at > total * 0.99 && checked >= 9, "{checked}");
        assert!(order[..4].iter().map(|&i| truth[i]).sum::<f64>() < total / 3.0);
        assert_eq!(e.left(at), Some(0.0));
        assert_eq!(e.fraction(at), Some(1.0));
        assert_eq!(e.done(), truth.len());
    }

    /// The reference predicts the `reference` technique's runs (the same
    /// ray tracer); a cached reference predicts with the time it took to
    /// compute, not the moment its read took.
    #[test]
    fn the_reference_predicts_the_reference_runs() {
        let (work, truth) = sweep();
        let mut e = SweepEstimate::new(work.clone());
        e.start(0, 0.0);
        e.finish(0, 0.01, Some(truth[0]));
        assert_eq!(e.predicted(0), Some(0.01));
        let last = work.len() - 1;
        assert_eq!(work[last].samples, Some(256));
        // Known to be cached before it is read: the same, and the read
        // itself takes no time to speak of.
        let mut before = SweepEstimate::new(work.clone());
        before.cached(0, truth[0]);
        before.baseline(0, 0.1);
        assert_eq!(before.predicted(0), Some(0.0));
        // Its samples are the reference's time above a render's fixed
        // part: unknown until something gives that.
        assert_eq!(e.predicted(last), None);
        e.baseline(0, 0.1);
        let p = e.predicted(last).unwrap();
        assert_eq!(before.predicted(last), Some(p));
        assert!(
            p <= 2.0 * truth[last] && truth[last] <= 2.0 * p,
            "{p} vs {}",
            truth[last]
        );
        // The others too, from that fixed part and the slope.
        assert!(e.predicted(1).is_some_and(|p| p > 0.0));
        assert!(e.left(0.01).is_some());
        // Without the fixed part, a few samples of a ray tracer say
        // nothing of many: no estimate rather than a wild one.
        let mut e = SweepEstimate::new(work.clone());
        e.start(9, 0.0);
        e.finish(9, truth[9], None);
        assert_eq!(work[9].samples, Some(4));
        assert_eq!(e.predicted(last), None);
        assert_eq!(e.left(truth[9]), None);
    }

    /// A piece under way counts for what it has left, never below zero;
    /// a share reported predicts it by its pace.
    #[test]
    fn the_piece_under_way_counts_its_rest() {
        let work = vec![
            work(Some(0), "dcs", 4),
            work(Some(1), "dcs", 4),
            work(Some(2), "dcs", 4),
        ];
        let mut e = SweepEstimate::new(work);
        e.start(0, 0.0);
        assert_eq!(e.left(1.0), None);
        e.part(1.0, 0.25);
        assert_eq!(e.predicted(0), Some(4.0));
        assert_eq!(e.left(1.0), Some(3.0 + 4.0 + 4.0));
        e.finish(0, 2.0, None);
        e.start(1, 2.0);
        assert_eq!(e.left(2.5), Some(1.5 + 2.0));
        assert_eq!(e.left(10.0), Some(2.0));
        assert_eq!(e.fraction(6.0), Some(0.75));
        // Probes' expectation, until a share is reported.
        e.start(2, 10.0);
        e.expect(6.0);
        assert_eq!(e.predicted(2), Some(6.0));
        e.part(12.0, 0.5);
        assert_eq!(e.predicted(2), Some(4.0));
        // Unknown pieces and indices are ignored.
        e.finish(7, 3.0, None);
        assert_eq!(e.index_of(0, Some(1)), Some(1));
        assert_eq!(e.index_of(1, None), None);
    }

    #[test]
    fn lines_are_fitted_nonnegative() {
        let (a, b) = fit_line(&[(4.0, 1.0), (16.0, 2.0), (64.0, 6.0)]).unwrap();
        assert!(a > 0.0 && b > 0.0, "{a} {b}");
        // Falling times: flat at their mean.
        assert_eq!(fit_line(&[(4.0, 2.0), (16.0, 1.0)]), Some((1.5, 0.0)));
        // A negative intercept: through the origin.
        let (a, b) = fit_line(&[(10.0, 1.0), (20.0, 3.0)]).unwrap();
        assert_eq!(a, 0.0);
        assert!(b > 0.0);
        assert_eq!(fit_line(&[(4.0, 1.0), (4.0, 2.0)]), None);
        assert_eq!(fit_line(&[]), None);
    }
}
