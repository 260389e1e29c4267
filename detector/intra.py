"""Lifetime and normal flow by RANSAC plane fitting with intra-pixel-area events.

For each event (normally one that passed :mod:`evedge.detector.buffer`):

1. the event is written into the Surface of Active Events of its polarity
   (:mod:`evedge.detector.sae`; ``per_polarity=False`` shares one surface),
   unless it continues its pixel's burst (``burst_lifetimes``, below, our
   addition): then the pixel keeps the time of the burst's first event, and the
   event is fitted at that time ``t_e``;
2. the ``N x N`` window of that surface centred on it gives the points
   ``(dx, dy, dt)`` in coordinates local to the event (``dt = t - t_e`` in us);
   pixels that never fired, and pixels outside the sensor, are not points;
3. 2-means on the window's timestamps (the current event included), initial
   centroids the window minimum and the current time, keeps the cluster holding
   the current event; a timestamp equidistant from both centroids joins that
   cluster, and a window whose timestamps all equal the current one is one cluster;
   when that cluster is degenerate (fewer than ``min_points`` points, or all on
   one line through the event, which happens on a clean ramp behind an
   axis-aligned edge when 2-means gives the middle row of timestamps to the old
   cluster), RANSAC uses all the window's points instead
   (``fallback_all_points``, our addition);
4. RANSAC: candidate plane ``t = t_e + a (x - x_e) + b (y - y_e)`` through the
   current event and two distinct random past points of the kept cluster
   (collinear samples skipped); residual of a point is the time distance from its
   intra-pixel square (half-size ``delta_px``) to the plane, in closed form
   ``max(0, |dt - a dx - b dy| - delta (|a| + |b|))`` (we use this time residual in
   microseconds, not the paper's normalised ``|n^T z - 1| / ||n||^2``, which only
   rescales it per candidate); inlier when the residual is at most
   ``inlier_threshold_us + inlier_threshold_rel * sqrt(a^2 + b^2)``; the candidate
   with most inliers wins (ties: smaller summed residual, then earlier trial);
5. least-squares refit of ``(a, b)`` on the winner's inliers (plane through the
   current event; plain residuals: the intra-pixel slack is for voting, a
   least-squares fit already averages the sub-pixel positions);
6. ``lifetime_us = sqrt(a^2 + b^2)`` and normal flow ``(a, b) / (a^2 + b^2)``
   px/us, reported in px/s.

No estimate (``valid`` False, NaN) when the kept cluster has fewer than
``min_points`` points (current event included) or fewer than 3, when the best
plane has fewer than ``min_inliers`` inliers (current event included), or when
the fitted plane is flat (``a = b = 0``: all inliers at the same time as the
current event, e.g. an edge's tied timestamps; the lifetime would be 0 and the
speed infinite).

Bursts (``burst_lifetimes``, our addition). A real edge rarely makes one event
per pixel: its log-contrast spans several thresholds ``C``, so each pixel fires
a burst while the edge sweeps its area (the simulated ``stripes``: 0.75 / 0.25
is 1.1 in log for ``C = 0.3``, three events per pixel per edge, at edge
positions about -0.33, -0.09 and +0.23 px from the pixel centre). These events
are intra-pixel-area events of one edge passage, but the paper's SAE keeps
only each pixel's newest one: pixels the edge has left hold their last event
(edge ~0.23 px past their centre) while the pixels the edge is crossing, the
current one included, hold an earlier one. The front of the plane is therefore
early by up to 0.55 lifetimes, more than the intra-pixel slack can absorb,
and every plane through it is too flat: on ``stripes`` the first event of a
burst got lifetimes 23 % short, the second 16 %, the last 4 %. We keep instead,
per pixel, the time of the burst's *first* event, so that all pixels of a
window refer to the same phase of the edge (the edge entering the pixel's
area): an event continues its pixel's burst when the pixel's previous event
has the same polarity, got a lifetime estimate ``L`` and fired at most
``burst_lifetimes * L`` before it (events of one passage are a fraction of a
lifetime apart; the next passage of an edge comes at least about one lifetime
later). Such an event is fitted at the burst's first time (the slopes, hence
lifetime and flow, describe the edge, not the event's phase in its burst);
an event without that support starts a new burst (the paper's SAE update).
``burst_lifetimes = 0`` is the paper's SAE. With one event per pixel per edge
nothing changes (the sweep's "mild" and "severe" scores are identical).

Measured (2026-11-23, pipeline with the event buffer, default parameters,
``burst_lifetimes`` 0 -> 1; median |relative error| against the simulator's
per-event truth, share of signal events with an estimate):
``stripes`` (``scenes/stripes.toml``): 17.2 % -> 2.0 %, 99.0 % -> 98.9 %;
per burst index 0 / 1 / 2: -23 / -16 / -4 % (signed) -> -1.7 / -0.2 / -0.6 %
(the Mueggler baseline, unfiltered: 6.9 %, 77 %); ``shapes_translation``
slow section (~35 px/s, 5-6 events per pixel and edge): 44.7 % -> 6.0 %
(estimates under half the truth 39.5 % -> 14.6 %), fast section 18.3 % -> 6.4 %;
sweep "burst" condition (3 events per pixel and edge): 23.3 % -> 1.8 %.
Values 0.5 / 2 give 2.5 / 2.0 % on ``stripes``, 8.5 / 5.8 % (slow) and
6.4 / 6.6 % (fast, with 2.5 / 5.2 % of the estimates over twice the truth
against 2.7 % at 1) on ``shapes_translation``: 0.5 breaks bursts whose early
events were underestimated, 2 merges distinct passages.
On the real ``stripes.mat`` the medians move from 10.0 / 5.9 ms (rows 32-63 /
64-127) to 12.1 / 6.9 ms, in line with the model-free delay between the
*first* events of neighbouring pixels' bursts (mode 11.75 / 6.25 ms; between
any event and its neighbour's newest event, which carries the same bias as
the paper's SAE, 9.25 / 5.75 ms).

Robustness options (issue 11), each a parameter, measured on the grid of
``benchmarks/robustness_grid.py`` (simulated stripes at 0/20/45/70 degrees,
10-2000 px/s, contrast ratio r = log-contrast / threshold 1.3-5, noise 0-5 Hz per
pixel, a rotating star and translating shapes; 96x72 px, 210 cells; "goals" are
issue 11's per-cell targets) and on ``scenes/stripes.toml`` (0.8 s, buffer on;
median |relative error|, signal events estimated, estimates > 2x off, noise
events given a lifetime). :func:`robust_params` turns the first three on.

Stale levels (``split_gap_ratio``, default 0 = the paper's 2-means). At low
contrast a pixel skips passages and keeps SAE times one or two passages old;
the paper's 2-means, initialised at the window minimum, lets the middle stale
level into the current cluster, and on a clean ramp behind an axis-aligned
edge it cuts the middle column in two (timing jitter around the centroids'
midpoint), leaving a cluster on one line. ``split_gap_ratio > 0`` replaces it
by single linkage in time from the current event (``_linkage_split`` in the
kernels): the cluster takes the nearest remaining time while its gap is at
most ``split_gap_ratio`` times the largest gap taken so far, and takes it
anyway while the cluster fixes no plane (this also replaces the all-points
fallback, which fitted planes through stale points). A nested 2-means that
kept splitting while a gap exceeded the kept part's span was tried first and
dropped: within one burst passage the columns' burst-start times spread as much
as the gap between columns (signal estimated 100 -> 70 % at 0 degrees, 200 px/s).
With the check below, ratios 2 / 3 / 5 put 28 / 31 / 32 of the 72 quick-grid
cells within the median-error goal and 11 / 19 / 21 within the > 2x goal; 3
(the preset's) and 5 are alike, 2 cuts passages.

Noise (``event_on_plane``, default 0 = off, the paper). A background event that
passes the buffer usually fires after an edge passed its neighbours (or before
it arrives): RANSAC through it finds planes among them, and with a threshold
relative to the candidate's lifetime a steep plane absorbs far points. With the
check the plane is refitted on the winner's *past* inliers alone and the event
must be an inlier of it (and those inliers must fix a plane). On
``stripes.toml`` (``benchmarks/robustness_grid.py --scene scenes/stripes.toml``,
steady state after 0.1 s): alone, noise events given a lifetime 22.6 % -> 10.0 %,
signal estimated 99.8 % -> 98.6 %, median error 2.0 % either way. Over all
events and without the start-up rule it cost more (estimated 98.9 -> 92.1 %,
median error 2.0 -> 3.8 %): in the first passage the paper's split leaves
one-line clusters whose past points fix no plane. The preset (linkage split +
check + start-up rule): median error 1.9 %, 0.88 % more than 2x off (defaults
0.97 %), 99.3 % estimated, 10.6 % of the noise events with a lifetime,
first-0.1 s error 1.1 % (defaults 2.5 %); Mueggler, unfiltered: 6.9 %, 0.22 %,
86.9 %, 7.2 %, 7.3 %. A variant that accepted events whose past inliers fix
no plane kept a little more signal but let more noise through (quick grid,
check alone: worst noisy cell 21.7 -> 29.3 %; 0 degrees, 200 px/s, r = 5,
5 Hz: 13.6 -> 29.3 %); it was dropped. A looser check (``event_on_plane`` 2 / 3 thresholds instead
of 1) keeps more signal (quick grid, with the linkage split: 33 -> 44 / 47 of 72
cells within the coverage goal) but fewer noisy cells stay within 10 % (9 -> 5 /
3 of 30); on the real ``stripes.mat`` the preset estimates 77.3 / 81.1 / 82.8 %
of the kept events at 1 / 2 / 3. The preset keeps 1.

Noise rules (each off by default; :func:`noise_params` = :func:`robust_params`
plus the first two; the parameters reach the kernels as one array, see
``_noise_kernels``). What is achievable, from the simulator's labels
(``evedge.bench.robustness``, "noise floor"): 6.9 % of the noise events (median
over the quick grid's 30 noisy cells, at most 9.3 %; full grid 7.5 / 9.9 %) fire
within half a lifetime of an edge's passage at their own pixel, where no timing
rule tells them from the edge's events. With the first ``robust_params()`` (linkage
split, event-on-plane check) the rest that got a lifetime were, on the cells
probed (96x72 and 64x48, 5 Hz), mostly events fitted to planes several times
slower than the edge (median 2-9x the true lifetime): stale levels of earlier
passages (a pixel skipping passages at low contrast keeps one; the levels of
successive passages make a staircase, a plane whose slope is the period) and
planes through other background events, which the relative inlier threshold and
the intra-pixel slack (both grow with the lifetime) let through; fewer were
events continuing a burst just after it ended. Quick grid (``--quick --preset
robust --intra ...``, 2026-12-01, with the stale-level rules of
``robust_params()``), each rule on top of ``robust_params()``: noise given a
lifetime (median / worst over the noisy cells; cells <= 10 %), cells within the
> 2x-off goal and within the coverage goal of 72, median signal estimated in the
noisy cells: ``robust_params()`` 8.1 / 15.7 %, 24/30, 38, 27, 77.7 %.

``newer_share_max`` (0.25 in the preset): no estimate when more than that share
of the window points on or above the fitted plane lie above it (newer than the
plane by more than the inlier band): an edge leaves the pixels it passed on its
plane and those ahead older, a slow false plane leaves the window's recent
events above it. 7.7 / 13.7 %, 24/30, 39, 25, 74.6 %. (Before the stale-level
rules, against ``min_inliers = 6`` on seven probed cells, it removed more noise
per signal event lost, e.g. 0 deg, 200 px/s, r = 1.3, 5 Hz: noise 17.9 -> 13.6 %
for signal 84.1 -> 80.4 %, where ``min_inliers = 6`` gave 16.1 % for 68.5 %.)

``lifetime_agreement`` (2 in the preset): no estimate when the lifetime is more
than that factor from the median of the inlier pixels' own latest estimates (at
least 3 known; fewer: kept). It needs those pixels' ``prev_lt`` in a strip's
halo too, so the strips publish it with the burst decision. 6.8 / 13.5 %, 26/30,
45, 26, 74.2 %.

Both (the preset before ``passage_gap`` joined it, below): 6.2 / 12.3 %, 28/30, 44, 25, 72.2 %; on the full grid (210
cells) 6.5 / 12.6 % and 91 of 100 noisy cells <= 10 % (``robust_params()`` 8.2 /
16.3 %, 78; defaults 25.1 / 48.4 %, 15), estimates > 2x off within the goal in
150 cells (130; 47), signal coverage goal 92 (95; 144). On the paper's defaults
(no linkage split, no stale-level rules) the two rules help little (14.2 %, 7/30
on the quick grid): they judge a fitted plane, and the defaults' planes through
stale points are what the split addresses. The price is coverage: on the real
``stripes.mat`` (buffer on) the share of the kept events with an estimate is
96.1 % (defaults), 71.1 % (``robust_params()``), 63.7 % / 60.7 % (with
``lifetime_agreement`` / ``newer_share_max`` alone), 56.9 % (the preset), with
medians (rows 64-127 / 32-63) 6.91 / 12.14, 6.64 / 11.82 and 6.56 / 11.85 ms
against the model-free 6.6 / 11.6 ms.

``burst_span_lifetimes`` (not in the preset): a burst continues only while the
event is at most that many lifetimes after the burst's first event
(``burst_lifetimes`` bounds only the gap to the previous event, so a background
event right after a burst continues it). At 1.5 on top of ``robust_params()``:
8.0 / 15.8 %, 25/30, 38, 27, 78.2 %, first-0.1 s error 6.3 -> 7.0 % (before the
stale-level rules: 11.3 -> 15.0 %). Kept as a measured option, not used.

``passage_gap`` (1 in the preset since 2026-12-03): no estimate for an event that starts a new
burst (by the burst rule; a start-up trial may still make it a continuation)
when its lifetime is more than that factor times the time since its pixel's
previous same-polarity event: two passages of an edge closer than one lifetime
are closer than one pixel. Aimed at the cells where pixels fire on few passages:
with equal ``C+``/``C-`` and a 2 % threshold mismatch, at ``r = 1.3`` a pixel
whose ``C-`` exceeds its ``C+`` stops firing after its first ON event, and more
pixels stop the more passages they see (``stripes`` at 64x48: 0.55 events per
pixel and edge at 200 px/s, 0.24 at 1000, 0.15 at 2000; ``r = 2.2``: 1.2-1.4).
At 2000 px/s the steady state then has ~4 current points per 5 x 5 window; the
3 % of its events that the preset estimates get 22-68x the truth: planes through
points of several passages, most of them start-up trials after an event without
estimate, lifetime 1.1-3.4x the gap to the pixel's previous event. Quick grid
(``--quick --preset noise --buffer-preset line --intra passage_gap=1``,
2026-12-03, load ~3): those four cells have no estimate left (> 2x-off goal 46
-> 51 of 72), noise <= 10 % 27 -> 28 of 30 (median 6.8 -> 6.1 %), medians over
the groups unchanged within 0.2 points, but signal estimated drops where
genuine bursts start with an event without estimate (the trial continuation,
gap well under one lifetime, is then refused): clean r >= 3 97.6 -> 96.9 %,
noisy 73.9 -> 70.2 % (10 px/s, r = 5, 5 Hz: 62.7 -> 43.3 %). Applied to bursts
started by the burst rule only (not after a trial) it changes none of those
cells (the bad planes come through trials). Full grid (``--preset noise
--buffer-preset line --workers 1``, 210 cells, 2026-12-03, load ~4), without ->
with ``passage_gap = 1``: cells within the median-error goal 177 -> 184, > 2x off
155 -> 175, signal estimated 93 -> 89, noise <= 10 % 92 -> 97 of 100 (median /
worst 6.8 / 13.2 -> 6.4 / 11.5 %); group medians unchanged but the noisy cells'
signal estimated 79.1 -> 76.7 % and > 2x off 0.44 -> 0.40 %, clean r >= 3 98.8 ->
98.6 %. The losses are the slow noisy cells (10 px/s, r >= 3, 5 Hz: signal
estimated -10 to -20 points; a noise event at the pixel is then its "previous
event" and the gap to it says nothing about the edge); no cell loses more than
3 points of signal elsewhere. On the real ``stripes.mat`` (buffer on) the preset
estimates 57.3 -> 51.5 % of the kept events, medians 6.63 / 11.91 -> 6.58 / 11.85 ms
(model-free 6.6 / 11.6); the defaults with it 96.1 -> 89.7 %. So it joins
``noise_params()`` (the preset that trades coverage for noise and accuracy) and
stays off in the defaults and ``robust_params()``.

Tried and dropped: the event's Mahalanobis distance from its past inliers'
positions (a fit to a thin band of points says nothing about a time off it): at
3.5 standard deviations noise -0.4 to -1.2 points on six probed cells for up to
-7.6 points of signal.

"At most 2x Mueggler's" per cell is out of reach for any estimator that keeps
the coverage goals: Mueggler's gives a lifetime to 0.5 % of the noise events
(median over the full grid's noisy cells) because it estimates 24 % of the
signal events there; the floor alone is 7.5 %, 15 times that (the preset is within
2x of Mueggler's in 10 of 100 noisy cells).

Start-up (``burst_startup``, default True). A burst continues only when the
previous event had an estimate, and nothing has one at the start of a
recording, so the first passage falls back to the paper's newest-event SAE and
its bias (-16 to -23 % per burst index, above). With the rule an event whose
previous same-polarity event has no estimate is first fitted as a
continuation, kept so when its own lifetime covers the gap; and an event
without estimate inside a burst leaves the burst's lifetime for the next one.
On a jittered burst edge with no history (``tests/detector``): estimates more
than 20 % off 11.6 % -> 6.3 %, estimated 95.9 -> 96.9 %; quick grid: median
first-0.1 s error over the noisy cells 28.8 -> 20.1 %; ``stripes.toml`` and the
real ``stripes.mat`` unchanged at the precision quoted below (2.0 %, 98.9 %;
96.0 %, 6.9 / 12.1 ms). The first 0.1 s is reported apart by the grid: at
10 px/s it is the first passage of pixels the edge already covered at t = 0,
whose first event has an arbitrary phase, and its error stays high (20-60 %).

Border (``border_px``, default 0). Events whose window the sensor's edge clips
get no estimate (their fit still sets the burst state); Mueggler et al. skip
2 px. All estimates more than 2x off at r = 5, clean, 200 px/s on the grid
(1.6 %) lay within 2 px of the border: a window without the pixels behind the
edge fits the stale pixels ahead. The price is the border's share of the
events (14 % at 64x48, 6 % at 128x128, 4 % at 240x180).

Skipped passages (``stale_fraction``, ``split_jump_check``; session 2 of
issue 11). At low contrast the simulated pixel misses passages: from the
simulator's truth, 48-57 % of the same-polarity edge passages of a pixel make
no event at r = 1.3 and 50-200 px/s (38-44 % at r = 1.7; 0-1.6 % at r >= 2.2).
Probing every estimate more than 2x off at r = 1.3, 200 px/s, 0 degrees against
the truth (passage index of every window point): all of them were over-
estimates, and 915 of the 930 estimates whose window held at most 3 neighbours
of the current passage were more than 2x off, against 10 of the 6761 with 4 or
more. Those windows are the current event, a few current points and stale
levels one and two periods older; the linkage split's forced growth (taken
while the cluster fixes no plane) jumped to a stale level and the next jump,
between two stale levels, then looked like an ordinary gap. ``stale_fraction =
0.5`` removes the times older than half the interval since the pixel's own
previous event of the same polarity (:func:`_stale_cutoff` in the kernels; not
applied when that event's lifetime says the window could reach so far:
``frac * interval <= 2 * half * lifetime``, which on the real ``stripes.mat``,
whose bursts are not all recognised as one, keeps 91.8 % of the kept events
estimated with the paper's split instead of 83.8 % unguarded). ``split_jump_check``
(:func:`_jump_ok`) refuses a linkage cluster whose largest gap was forced and is
more than ``split_gap_ratio`` times every other gap it took. Quick probe,
preset before -> with both, > 2x off / estimates: r = 1.3, 200 px/s, 0 degrees
12.0 % / 7691 -> 0.1 % / 6458; r = 1.7, 50 px/s, 20 degrees 6.1 % / 13560 ->
0.2 % / 12104; r = 5, 200 px/s 0.9 -> 0.4 %. Over the grid (session-1 preset
with each): cells within the > 2x goal 85 -> 123 with both (coverage goal 127
-> 103); without the guard 108 with ``stale_fraction`` alone, 124 with both, and
fractions 0.3 / 0.5 / 0.7 alike (124 / 124 / 124 cells, coverage 99 / 102 / 103).

Start-up (``startup_reach``). In the first passage the window cannot hold the
plane's older times yet: pixels upstream never fired, or fired at the start
with whatever phase the edge had reached. Such estimates are short (signed
median -80 / -63 / -34 / -7 % in 0-10 / 10-30 / 30-60 / 60-100 ms on the
rotating star, r = 5; -57 % in 100-200 ms for stripes at 10 px/s, whose
lifetime is 100 ms). With ``startup_reach = 1`` an estimate whose plane reaches
back (``half (|a| + |b|)`` from the event) before the first event since the
reset is not reported (:func:`_history_short`): rotating star, estimated / median
error, 30-60 ms 837 / 34 % -> 219 / 31 %, 60-100 ms 1238 / 6.6 % -> 931 / 4.6 %;
from 200 ms on unchanged. It cannot catch every biased estimate (a short
estimate has a short reach); ``startup_reach = 2`` removes nearly all of them
but, at 10 px/s, also correct estimates up to 0.4 s. Grid, the preset with
``stale_fraction`` and the check, ``startup_reach`` 0 -> 1 -> 2: cells within
the median goal 123 -> 126 -> 127, > 2x goal 123 -> 130 -> 134, coverage goal
103 -> 95 -> 90 (the lost cells are stripes at 10 px/s, whose whole recording is
the first passage), noise given a lifetime <= 10 % 63 -> 78 -> 96 of 100 (a noise
event's plane through old points reaches far back; in recordings of 0.25-1.2 s
this is most of them, in long ones the rule stops acting after a few lifetimes:
it is no noise filter). Median first-0.1 s error over the noisy cells 7.8 ->
5.2 %. The preset takes 1 (the literal rule).

On the grid (96x72, all 210 cells), cells within each goal, paper-like
defaults before this issue -> the preset of session 1 -> today's preset
(``benchmarks/robustness_grid.py --intra split_gap_ratio=3 --intra
event_on_plane=1 --intra split_jump_check=1 --intra stale_fraction=0.5 --intra
startup_reach=1``): median error 77 -> 115 -> 126, estimates > 2x off <= 1 %
47 -> 85 -> 130, signal estimated 139 -> 127 -> 95, noise given a lifetime
<= 10 % 15 -> 42 -> 78 of 100. Medians over the cells (median error / > 2x off /
estimated): clean r >= 3 1.8 / 0.87 / 100 % (defaults), 1.6 / 0.05 / 98.8 %
(preset); clean r < 3 5.4 / 10.3 / 86.7 %, 3.6 / 0.18 / 68.3 %; noisy 4.5 / 4.4 /
95.0 %, 3.6 / 1.5 / 80.0 %. The coverage lost at low contrast is where the
window holds fewer than 4 points of the current passage (above). On the real
``stripes.mat`` the session-1 preset estimated 77.3 % of the kept events instead
of 96.0 % (linkage alone 89.4 %, the check alone 84.5 %), with medians 6.7 /
11.8 ms (rows 64-127 / 32-63) against 6.9 / 12.1 ms and the model-free 6.6 /
11.6 ms; today's preset estimates 71.1 % (6.64 / 11.82 ms; without
``event_on_plane`` 79.9 %; the paper's split with ``stale_fraction`` alone
91.8 %, with ``startup_reach`` alone 95.2 %). This is why the preset is not the
default.

Schedule (``ls_first``, issue 12; default 0.5, 0 = the paper's RANSAC alone). Least
squares first: the plane through the current event is fitted by least squares to the
whole kept cluster (after 2-means, or on all points in the fallback); when every
point's intra-pixel residual is within ``ls_first`` times that plane's inlier
threshold, every point is an inlier of a plane of RANSAC's model class, so no
hypothesis can have more, and the result is the refit on all the points (the
sums, in the same order, are the refit's): no trial runs. Otherwise RANSAC runs
as before, with the same draws (a window that fails the check gets the same bytes
as with ``ls_first = 0``). The margin matters: at 1 (every point an inlier, just)
the least-squares plane, whose relative threshold grows with its slope, also
absorbs points RANSAC's winner leaves out, and on the quick grid's noisy cells the
median error rose 5.39 -> 5.71 % (defaults); at 0.5 it is 5.44 %. Windows captured
from the stream kernel (``benchmarks/schedule_study.py``, first 30,000 kept
events; 2026-12-02): the least-squares plane has every point an inlier in 16.5 %
of the clusters on the real ``stripes.mat`` and 81.7 % on the simulated
``shapes_translation``; today's RANSAC runs 11.1 / 3.3 trials per cluster there,
finds its final best at trial 4.8 / 1.9 and hits the cap of 20 in 20.4 / 2.8 % of
them; in the clusters with full consensus it ran 2.8 / 1.7 trials and its winner
had full consensus too in 80.6 / 93.0 %. Seeding RANSAC with the least-squares
plane as hypothesis 0 (10.5 / 1.9 trials) and LO-RANSAC (a least-squares refit
after every new best, scored as a further hypothesis: 10.3 / 1.85 trials) change
little: on ``stripes.mat`` the best plane's inlier share is ~0.7 (6.6 of 9.1
points), and at that share the 0.999 bound needs ~11 trials whoever finds the
plane; they were not built. Measured (``benchmarks/stop_rule.py --schedule``,
2026-12-02, load 2.2-2.7, estimator CPU per kept event best of 5 alternated (a
second run at load 7.6-8.2: 1.14 / 1.09 / 1.05x on the three simulated scenes,
842 -> 772 ns, 1.09x, on ``stripes.mat``; the accuracy figures are deterministic),
accuracy against the simulator's truth with the buffer; 0 -> 0.5): simulated
``shapes_translation`` 454 -> 399 ns (1.14x), median error 6.08 -> 6.11 %,
> 2x off 5.91 -> 5.95 %, estimated 98.83 -> 98.88 %; ``stripes`` (1 s) 426 -> 361
ns (1.18x), 2.03 -> 2.03 %, 3.05 -> 3.10 %, 99.14 -> 99.14 %; ``shapes_rotation``
387 -> 349 ns (1.11x), 6.30 -> 6.35 %, 7.56 -> 7.62 %, 96.22 -> 96.32 %; the real
``stripes.mat`` 669 -> 674 ns (no gain), estimated 96.07 -> 96.12 %, medians 6.91 /
12.14 ms either way (99.2 % of the estimates unchanged). Quick grid
(``benchmarks/robustness_grid.py --quick``, medians over the cells' figures, 0 ->
0.5; median error / > 2x off / estimated): defaults, noisy cells 5.39 -> 5.44 %,
6.35 -> 6.36 %, 93.27 -> 93.32 %; clean r < 3 5.29 -> 5.29 %, 3.28 -> 3.23 %, 89.85 ->
89.89 %; clean r >= 3 unchanged within 0.01; ``--preset robust`` and ``noise``:
in every group median error and > 2x off at most 0.012 points higher (mostly
lower), estimated within 0.07 points. 0.25 is as neutral and a little slower on shapes (1.11x).

Ring refit (``refine_window``, default 0 = off, the paper; 9 in :func:`robust_params`
and :func:`noise_params`). At low contrast each pixel fires once or twice per passage at
a point of the edge's crossing that its threshold (mismatch ``contrast_sigma``) and its
leftover from the previous passage set: the timestamps scatter about the plane by a few
per cent of a lifetime, and a 5 x 5 window's ~10 points of the current passage leave
that scatter in the slopes (r = 2.2, 200 px/s, 0 degrees, ``noise_params()``: estimates
5-95 % at 0.87-1.06 of the truth, median error 4.2 %). A larger window for the whole
fit costs coverage where the larger window holds more stale levels (``window_size = 7``
on the quick grid: signal estimated at 10 px/s down 8-16 points, estimator CPU 2x) and
bias where the flow varies across it. The ring refit keeps the fit on the paper's
window and only adds, to its least-squares refit, the points of the larger window that
lie on the fitted plane (residual to it, with the inliers' least-squares offset, less
the intra-pixel slack, within the inlier threshold): the same r = 2.2 cell gives
0.92-1.03, median 2.4 % (9: 1.7 %). The ring makes or removes no estimate itself (the
rules that read the lifetime, bursts and start-up, may decide a few events
differently). Quick grid, ``--preset noise`` (2026-12-02, load ~1), without -> ring 7
-> ring 9: cells within the median-error goal 38 -> 50 -> 53 of 72, > 2x off goal 44 ->
43 -> 43, signal goal 25 -> 25 -> 25, noise <= 10 % 28 -> 28 -> 28 of 30, cells where the
median error is above half Mueggler's 21 -> 11 -> 9 of 38; medians over the cells,
clean r >= 3 1.3 -> 0.8 -> 0.5 %, clean r < 3 3.7 -> 2.1 -> 1.7 %, noisy 4.0 -> 2.7 ->
2.1 %; worse: the rotating star (a plane over a wider window averages a lifetime that
varies with the radius: 4.6 -> 5.7 -> 6.1 %, 7.1 -> 8.2 -> 8.0 %, 7.4 -> 8.6 -> 8.3 %)
and slow high-contrast stripes (10 px/s, r = 5: 0.7 -> 1.0 -> 1.7 %); estimator CPU
summed over the cells 4.1 -> 4.3 -> 4.4 s. Full grid (96x72, 210 cells, ``--preset noise
--buffer-preset line --intra refine_window=R --workers 1``, 2026-12-02, load 1.3-2.2), R =
7 / 9 / 11: median-error goal 172 / 177 / 176 of 210 (135 without the ring), > 2x off
153 / 155 / 157, noise <= 10 % 91 / 92 / 90 of 100, cells above half Mueggler's median
31 / 23 / 12 of 131, medians clean r < 3 2.1 / 1.7 / 1.4 %, noisy 2.2 / 1.9 / 1.7 %; the
first-0.1 s error over the noisy cells 5.9 / 7.2 / 8.7 % (the ring reaches pixels whose
history is the start's), slow high-contrast stripes (20 degrees, 10 px/s, r = 3) 1.9 /
2.2 / 2.8 %, estimator CPU summed over the cells 27.1 / 31.3 / 34.6 s; the rotating star
5.1-6.6 % for all three. The presets take 9 (11 gains little more and plane over 11 x
11 px is a strong assumption on real scenes). Again with ``curvature_f = 16`` in the presets
(2026-12-07 21:4x UTC, ``--intra refine_window=11``, with the line rule): ``noise_params()`` 197 /
184 / 93 / 99 -> 199 / 185 / 93 / 99 goal cells, above half Mueggler's 18 -> 7 of 131, first-0.1 s
error over the noisy cells 3.3 -> 4.2 %; ``robust_params()`` 188 / 155 / 98 / 87 -> 187 / 154 / 99 /
86 (above half Mueggler's 19 -> 7); better at 1000-2000 px/s, low contrast (r = 1.3, 70 degrees,
2000 px/s 4.6 -> 2.1 %), worse on slow stripes (0 degrees, 10 px/s, r = 3: 2.5 -> 4.2 %) and the
rotating star (r = 5: 3.0 -> 4.0 %), intra CPU +13 %. Mixed: the presets keep 9. On the real ``stripes.mat``
(``robust_params()``) estimated 71.1 -> 71.3 % of the kept events, medians 6.64 / 11.82
-> 6.69 / 11.87 ms (model-free 6.6 / 11.6). The strips' halo is the ring's radius (the
events read that far). ``refine_tolerance`` (default 1, the bytes of before) admits a ring
point only within that fraction of the fit's inlier threshold, against the rotating star's
curved time surface: full grid with the line rule (``--intra refine_tolerance=T``,
2026-12-07, load ~2), goal cells median error / > 2x / signal / noise, ``noise_params()``
184 / 175 / 89 / 97 (T = 1), 188 / 174 / 89 / 97 (0.5), 189 / 173 / 89 / 96 (0.25);
``robust_params()`` 170 / 134 / 97 / 69, 172 / 135 / 97 / 71, 174 / 134 / 97 / 73; the
rotation cells 5.7-6.6 -> 4.9-5.9 % (0.25), r = 1.7 at 2000 px/s 2.7-3.0 -> 3.2-3.4 %.
Mixed small gains: not in the presets.

Curvature (``curvature_f``, default 0 = off, the paper's plane; 16 in both presets since
2026-12-07). A plane fitted on the past points of a window gives the time surface's slopes at
their centroid, behind the event; where the edge's normal speed changes across the window
(rotation, curved edges) those are not the event's. On the rotating star (r = 5, clean,
``noise_params()`` with the line rule, before the change) the estimated normal lagged the truth's by
a median 5.4 degrees and the error followed the angle between motion and normal (-10.6 % at cosine
0.6-0.8, +4.7 % at 0.9-0.97). The ring refit now also fits ``dt = a dx + b dy + c dx^2 + d dx dy + e
dy^2`` (``+ t0`` with ``refit_intercept``) on the same points (the moments are summed with the plane's,
the 6 x 6 normal equations solved by ``L D L^T`` in the scratch, :func:`._intra_kernels._quad_solve`) and takes its
slopes at the event when ``F = ((RSS_plane - RSS_quad) / 3) / (RSS_quad / dof) > curvature_f``. That
cell: lag 1.1 degrees, median |error| 6.7 -> 3.1 %. The start-up rule (``startup_reach``) keeps judging
the window's history with the plane on the same points, as it was measured: with the quadratic's
(longer, unbiased) slopes it refused 0.5-2 points more of the rotation cells' signal in 0.1-0.2 s
(``benchmarks/cell_breakdown.py --kind rotation --r 3``: 95.4 -> 94.2 %; with the plane's 95.2 %). Full
grid (``benchmarks/robustness_grid.py --preset P --buffer-preset line --workers 2 [--intra
curvature_f=F]``, 2026-12-07 20:2x-21:2x UTC, load ~2), goal cells median error / > 2x / signal / noise:
``noise_params()`` 193 / 182 / 93 / 99 -> 196 / 183 / 89 / 99 (F = 4) and 197 / 184 / 91 / 99 (F = 16),
both with the quadratic's slopes for the start-up rule, and **197 / 184 / 93 / 99** (16, the plane's);
``robust_params()`` 184 / 155 / 98 / 87 -> 188 / 153 / 97 / 87 (16, quadratic's) and 188 / 155 / 98 / 87
(16, plane's); cells above half Mueggler's median 23 -> 18 and 24 -> 19. Costs: the presets'
estimator CPU +20 / +17 / +5 % per event on the rotation cell / shapes_translation /
``stripes.mat`` (whose estimates and medians are unchanged; with Gaussian elimination instead of
``L D L^T`` +28 / +23 / +7 %, the same decisions; scratch script alternating the settings, best of 5). A test checks the exact gradient on
a front with integer timestamps on a quadratic, where the plane is 0.8 % off.

Presets, 2026-12-07: ``startup_reach = 1.5`` (was 1) and ``burst_reuse = 2`` (was 0) joined
:data:`ROBUST`, so both :func:`robust_params` and :func:`noise_params`. ``robust_params()``, full grid
with the line rule: 170 / 134 / 97 / 69 -> 184 / 155 / 98 / 87 goal cells (paper buffer 161 / 130 / 97 /
76 -> 175 / 150 / 99 / 86), noise given a lifetime 8.3 -> 7.0 %, estimator CPU 39.4 -> 13.5 s; on
``stripes.mat`` 71.3 -> 75.7 % of the kept events estimated, medians 6.69 / 11.87 -> 6.79 / 12.03 ms.
``noise_params()``, full grid, ``benchmarks/robustness_grid.py --preset
noise --buffer-preset line --workers 2 --intra ...`` (one session, load ~2, 1 minute each), goal
cells median error / > 2x / signal / noise: before 184 / 175 / 89 / 97; ``burst_reuse=2`` 186 / 179 /
93 / 94; ``startup_reach`` 0 / 0.5 / 1.5 / 2: 180 / 171 / 91 / 90, 180 / 171 / 91 / 92, 192 / 178 /
88 / 99, 197 / 178 / 86 / 99; with ``burst_reuse=2`` too, 1.5: **193 / 182 / 93 / 99**, 2: 197 /
184 / 89 / 99. 1.5 with reuse is above the preset before on every goal; with the paper's buffer
175 / 170 / 89 / 95 -> 183 / 175 / 93 / 98. Costs: the group medians of signal estimated fall (with
the line rule clean r < 3 72.4 -> 70.6 %, noisy 76.7 -> 72.8 %; the worst clean r >= 3 cell 71.6 ->
58.3 %: slow edges wait longer for history), cells above half Mueggler's median 23 -> 23 (25 -> 26
with the paper's buffer). Gains beside the goals: noise given a lifetime 6.4 -> 5.9 % (median over
the noisy cells), first-0.1 s error over the noisy cells 7.1 -> 3.3 %, estimator CPU over the grid
32.9 -> 20.7 s; on ``stripes.mat`` 51.5 -> 59.6 % of the kept events estimated, medians of rows
64-127 / 32-63 6.58 / 11.85 -> 6.63 / 11.94 ms (model-free 6.6 / 11.6).

Burst reuse (``burst_reuse``, default 2 since 2026-12-03, the setting A below, neutral with the
defaults; 0 = off, every event fitted, in :func:`robust_params` and :func:`noise_params` until
2026-12-07 (see "presets, 2026-12-07"); with
``burst_warm_refit`` and ``burst_reuse_inliers``). The events of one passage of the edge
at a pixel (a burst, ``burst_lifetimes``) share one lifetime, so a continuing event may
take the burst's plane instead of fitting its window again: the estimator's cost
(issue 12) then falls with the share of continuing events (``stripes.mat`` ~47 % of
the kept events, simulated ``shapes_translation`` ~79 %). Taking the burst's first
fit for all its events (``2a1c4b7``) is not neutral: quick grid (``benchmarks/
robustness_grid.py --quick --preset P --buffer-preset line --workers 1 --intra
burst_reuse=...``, medians over the cells, median error / > 2x off / estimated),
defaults: clean r >= 3 1.39 -> 1.73 %, 1.45 -> 1.85 %, first 0.1 s 2.18 -> 2.86 %;
noisy 5.36 -> 5.36 %, 5.52 -> 6.08 %, 93.6 -> 94.5 %; ``noise_params()``: clean r >= 3
> 2x 0.24 -> 0.46 %, noisy median 1.90 -> 2.11 %, estimated 73.9 -> 82.1 %, noise
given a lifetime 6.84 -> 7.04 %. Two causes. (1) The > 2x share: a fit of
``fallback_all_points`` (the current passage's cluster degenerate, RANSAC on all the
window's points, often a plane through the previous passage ~10x too steep, e.g. at
the sensor's border where the clipped window holds two current points) is wrong for
the one event without reuse, and the burst's next events refit right once their
neighbours have fired (clean stripes 20 degrees, 200 px/s, r = 5: 376 steady-state
estimates > 2x off, by the event's index in its burst 146 / 145 / 70 / 13; with
reuse 589: 146 / 146 / 146 / 132); reuse spreads it over the burst. Such fits are
never stored (the burst's next event is fitted again). (2) The median error: the
burst's first event sees only the neighbours behind the edge, its later events see
the ones that fired since; excluding fallback fits alone leaves clean r >= 3 at
1.67 % (``burst_reuse = 1, burst_reuse_inliers = 0``). Hence the refits before reuse: ``burst_reuse = k``
refits the burst until it stored ``k`` fits. The warm refit (``burst_warm_refit``,
default) starts from the stored plane: its inliers among the window at the burst's
first time, least squares, the rules that need no cluster; it costs the gather and
one pass (no 2-means, trial or compaction) and is better constrained than the
burst's first fit (more points on the plane).

Settings measured (``--intra burst_reuse=2``: A, warm refits with the default inlier
floor ``burst_reuse_inliers = 8``; A10 / A0: A with ``--intra burst_reuse_inliers=10`` /
``0``; ``--intra burst_reuse=3 --intra burst_warm_refit=false``: B, full refits, floor 8;
B10: floor 10), figures off -> setting, medians over the cells (median error / > 2x
off / estimated; noisy also noise given a lifetime and cells with it <= 10 %), summed
intra CPU, 2026-12-03, load 0.3-5.7. Quick grid, defaults: off clean r >= 3 1.39 / 1.45
/ 100 %, first 0.1 s 2.18 %; clean r < 3 5.07 / 3.11 / 93.52 %; noisy 5.36 / 5.52 /
93.59 %, noise 26.30 %, 2 of 30 cells; 2.8 s. A: 1.38 / 1.45 / 100 %, first 1.77 %; 5.07
/ 3.15 / 93.52 %; 5.05 / 5.48 / 93.59 %, 26.31 %, 2; 2.4 s. A10: 1.41 / 1.45 / 100 %,
first 2.13 %; 5.07 / 3.11 / 93.52 %; 5.08 / 5.52 / 93.59 %, 26.31 %, 2. A0: 1.38 / 1.45
/ 100 %, first 1.64 %; 5.07 / 3.05 / 93.55 %; 5.00 / 5.47 / 93.85 %, 26.32 %, 2. B: 1.40
/ 1.45 / 100 %, first 2.21 %; r < 3 unchanged; 5.26 / 5.52 / 93.59 %, 26.30 %, 2; 3.0 s
(B10: 1.40, noisy 5.32 %, else as B). Quick grid, ``--preset noise``: off 0.50 / 0.24 /
97.57 %; 1.56 / 0.00 / 71.96 %; 1.90 / 1.16 / 73.89 %, noise 6.84 %, 27 of 30; 8.3 s. B:
0.50 / 0.24 / 97.65 %; r < 3 unchanged; 1.93 / 1.17 / 74.00 %, 6.85 %, 27; 6.7 s (B10:
0.51 / 0.25 / 97.64 %, 1.93 / 1.16 / 74.02 %, 6.84 %). A10: 0.51 / 0.25 / 97.76 %; 1.56 /
0.00 / 72.01 %; 1.95 / 0.95 / 78.39 %, 6.92 %, 26; A0: 0.51 / 0.32 / 97.77 %; 1.56 / 0.00
/ 72.03 %; 1.97 / 1.04 / 80.67 %, 7.02 %, 26. Full grid (96x72, 210 cells, the same
commands without ``--quick``), defaults: off 1.82 / 0.87 / 100 %, first 2.69 %; 5.28 /
4.57 / 88.53 %; 4.43 / 4.26 / 94.96 %, 26.81 %, 14 of 100; 15.7 s. A: 1.83 / 0.87 / 100 %,
first 2.79 %; 5.28 / 4.55 / 88.53 %; 4.42 / 4.21 / 95.02 %, 26.82 %, 14; 13.9 s. A10:
1.83 / 0.87 / 100 %, first 2.70 %; 5.28 / 4.57 / 88.51 %; 4.42 / 4.23 / 94.99 %, 26.81
%, 14. A0: 1.83 / 0.87 / 100 %, first 2.88 %; 5.28 / 4.35 / 89.53 %; 4.41 / 4.39 / 95.30
%, 26.84 %, 14 (the noisy > 2x median +0.13 points; over the 100 noisy cells its mean
-0.20 points, 48 cells up, 41 down; A0 with k = 3: 4.38 %). B: 1.82 / 0.87 / 100 %,
first 2.69 %; 5.28 / 4.57 / 88.53 %; 4.43 / 4.26 / 94.98 %, 26.81 %, 14; 12.9 s (B10:
noisy 4.25 / 94.97 %, else as B). Full grid, ``--preset noise``: off 0.78 / 0.04 /
98.79 %; 1.68 / 0.01 / 72.38 %; 1.87 / 0.44 / 79.07 %, 6.83 %, 92 of 100; 51.3 s (3.7 s
of it compilation in the first cell). B and B10: the same figures except noisy
estimated 79.09 %; 40.5 / 46.1 s. A0: 0.79 / 0.04 / 98.79 %; r < 3 unchanged; 1.86 /
0.38 / 82.84 %, 7.06 %, 88. So A is neutral with the defaults (every group's median
error and > 2x share within 0.04 points, estimated and noise within 0.01; the first
0.1 s +0.10 points on the full grid, -0.41 on the quick one) and B with both presets
(within 0.03 points everywhere, on both grids); A0 is neutral on the quick grid only;
with ``noise_params()`` every warm setting gives more estimates (+3.8 to +6.8 points in
the noisy cells) and more noise events a lifetime (+0.06 to +0.2 points). The lead, full
grid with the line rule (``--workers 1 --buffer-preset line --intra burst_reuse=K``,
2026-12-03 10:24 UTC, load ~1.5; medians clean r >= 3 / r < 3 / noisy, goal cells median
error of 210): K = 0 1.8 / 5.3 / 4.4 %, 82; K = 2 (A, the default since) 1.8 / 5.3 / 4.4 %,
84; K = 1 (warm refits never, floor 8) 2.0 / 5.3 / 4.6 %, 75: one stored fit is not
enough. With the paper's buffer, K = 0 -> 2: 80 -> 82 cells, medians within 0.1 (README).

Estimator CPU per kept event (``filter_events`` then :func:`estimate_lifetimes`, the
settings alternated in one process, best of 5 (noise: 3), ``time.process_time``;
scratch script, not in ``benchmarks/``; 2026-12-03 09:54 UTC, load 0.9-1.4),
``stripes.mat`` / simulated ``shapes_translation`` (2 s): defaults off 867 / 466 ns; A
664 / 235 ns (1.31x / 1.99x); A10 681 / 268 ns (1.27x / 1.74x); A0 591 / 201 ns (1.47x
/ 2.32x); B 848 / 328 ns (1.02x / 1.42x); B10 1.01x / 1.32x; ``burst_reuse = 1`` with
floor 0 (reuse after the first stored fit; not neutral) 539 / 157 ns (1.61x / 2.96x).
Other runs (load 1.2-5.5): A 1.44x / 2.02x, A10 1.16-1.32x / 1.70-1.74x, A0 1.30-1.49x /
2.20-2.31x, B 0.92-1.04x / 1.32-1.42x: +-0.1 run to run. ``noise_params()``: off 3216 /
2409 ns; B 3164 / 1401 ns (1.02x / 1.72x); B10 1.02x / 1.68x; A (not neutral there) 2463
/ 739 ns (1.31x / 3.26x). Estimated on ``stripes.mat``: defaults 96.12 % -> A 96.16,
A0 96.31, B 96.12 %; ``noise_params()`` 57.29 % -> B 57.76, B10 57.69, A 65.87 %. Of
``stripes.mat``'s kept events with A0 22 % take a stored plane, 23 % are warm refits
(0.2 % of them fail and are fitted), 55 % are fitted (bursts' first events, bursts
without plane); ``shapes_translation`` 57 / 19 / 24 %: on ``stripes.mat`` the bursts'
first fits are most of the cost, whatever the reuse.

Why the noise preset resists: its fit rules reject many continuing events' refits,
which reuse skips (real ``stripes.mat``, first 150,000 kept events, estimated without ->
with plain reuse: all rules 55.8 -> 65.8 %; without ``split_gap_ratio`` 60.0 -> 64.0 %;
without ``newer_share_max`` 63.0 -> 71.0 %; without ``lifetime_agreement`` 59.4 ->
68.6 %), and the warm refit has no linkage split either (``stripes.mat`` estimated
57.3 -> 65.9 % with A, 65.0 % with A10, 66.1 % with A0). Only full refits with an inlier floor keep the rejections. Also
measured on the quick grid (same cells and scoring, scratch variants, not kept; defaults
unless said): plain reuse after k full refits, fallback fits stored: k = 2: clean r >=
3 1.42 %, > 2x 1.60 %, noisy > 2x 6.02 %; k = 3: 1.40 / 1.57 / 5.39 %; with fallback
fits not stored and no inlier floor, k = 2: noisy > 2x 5.67 %; ``noise_params()`` with
``burst_reuse_inliers`` 10 / 12 / 14 at k = 2 (full): noisy median 1.97 / 1.96 / 1.91
%, noise 6.87 / 6.85 / 6.83 % (14 is neutral, and as slow as no reuse: 0.99x / 1.24x);
k = 3 (full) without floor: noise 6.89 %; warm k = 2 / 3 with floor 12: noise 6.90 /
6.94 %; warm k = 2 / 3 also running the linkage split on the window: noise 6.94 / 6.92
%, clean r >= 3 > 2x 0.32 / 0.31 %. A warm start only when every window point is on
the stored plane (within ``ls_first`` thresholds, then least squares on all): the
window almost always holds the previous passage's points, so it fires for 0.3 % /
14 % of the events (``stripes.mat`` / ``shapes_translation``), no speed. Reuse only
while the window (count and summed times of its cells) is unchanged since the fit:
1.06x / 1.23x, and with ``noise_params()`` estimated 73.89 -> 73.72 %. Refit when the
event is over 0.5 / 1 stored lifetimes after the stored fit: clean r >= 3 1.56 /
1.69 %, > 2x 1.85 %; refit every second event: 1.51 / 1.57 %; reuse once two
consecutive fits agree (plane within 5-20 %): 1.42 / 1.56-1.57 % (consecutive fits see
nearly the same window: they agree whether right or wrong); the stored plane as
RANSAC's only hypothesis for every continuing event (no reuse): 1.02-1.18x, and with
``noise_params()`` estimated 73.89 -> 73.69 %, clean r >= 3 > 2x 0.24 -> 0.26 %.

Randomness: trial ``k`` of the event with global index ``g`` (position in the
stream since the last :meth:`IntraPixelLifetime.reset`) draws
``splitmix64(key + 2k)`` and ``splitmix64(key + 2k + 1)`` with
``key = splitmix64(seed ^ splitmix64(g))``, so results do not depend on chunking.

Defaults, chosen by ``benchmarks/sweep_intra_params.py`` (synthetic straight
edges on a 48x48 sensor, 8 speeds 20-5000 px/s (lifetimes 50 ms-200 us) x 6
angles; "mild" noise: sub-pixel position error uniform +-0.25 px and time
jitter 2 % of the lifetime; "severe": the same with 5 % jitter and 10 % of the
events moved by up to +-5 lifetimes; "burst": 3 events per pixel and edge at
edge positions -1/3, 0, +1/3 px (each +-0.1 px), jitter 2 %; score = share of
events with an estimate within 10 % of the truth, mean of the three
conditions; measured 2026-11-23; the first two conditions alone, the sweep
before "burst" was added, gave the same ranking):

``inlier_threshold_us = 50`` and ``inlier_threshold_rel = 0.2``
    Score 0.802 (mild: 0.751, 100 % with estimate, median relative error
    5.2 %; severe: 0.689, 98.3 %, 6.0 %; burst: 0.965, 100 %, 1.8 %). A purely
    absolute threshold does worse (0.777 / 0.784 / 0.787 at 10 / 50 / 200 us),
    since the timestamp jitter of an edge is a fraction of the time it needs
    per pixel; with a relative part of 0.1-0.4 the score is flat
    (0.796-0.802; 10 us + 0.2 ties at 0.802); the absolute part covers the
    sensor's time resolution.
``delta_px = 0.25`` (the paper's)
    0.802 against 0.731 with ``delta_px = 0`` (plain RANSAC) and 0.796 at 0.5.
``refit_intercept = True``
    The least-squares refit gets a free time offset: 0.802 against 0.680 when
    the plane is forced through the current event, whose own timing error
    then tilts the plane (median error 8.6 % instead of 5.2 % in "mild").
``fallback_all_points = True``
    0.802 against 0.775 without; estimates for 100 % / 98.3 % / 100 % of the
    events instead of 99.3 % / 95.5 % / 98.9 %.
``burst_lifetimes = 1``
    0.802 against 0.534 with the paper's SAE (0: "burst" scores 0.161, median
    error 23 %), 0.700 at 0.5 and 0.803 at 2 (chosen against 2 on the
    simulated scenes, see above; mild and severe are unchanged by it).
``max_trials = 20``, ``stop_probability = 0.999``
    0.798 / 0.802 / 0.802 / 0.802 for 5 / 10 / 20 / 40 fixed trials;
    adaptive stopping gives 0.802 at 0.999 (0.800 at 0.99) for about 1.3x
    the speed of 20 fixed trials on stripes.mat.
``min_points = 5``, ``min_inliers = 5``
    Three points always fit a plane; 3 / 4 / 5 inliers score alike (0.802 /
    0.803 / 0.802), 6 / 8 lose estimates (0.783 / 0.672); 5 asks for two
    votes beyond the sample at no cost.

Accuracy of the defaults on the same edges (median relative lifetime error,
share of events with an estimate, per speed over 6 angles): noise-free 0.00 %
(0.05 % at 5000 px/s, from 1-us timestamp rounding) and 100 %; "mild"
5.1-5.3 % and 99.9-100 %; "severe" 5.9-6.0 % and 98.1-98.6 %; "burst"
1.7-1.8 % and 100 %, flat across 20-5000 px/s because all noise is in units
of the lifetime.

References
----------
.. [1] S. Lee, H. Kim, H. J. Kim, "Edge Detection for Event Cameras using
       Intra-pixel-area Events", BMVC 2019, sections 2.3-2.4.
.. [2] E. Mueggler, C. Forster, N. Baumli, G. Gallego, D. Scaramuzza,
       "Lifetime Estimation of Events from Dynamic Vision Sensors", ICRA 2015.
.. [3] M. A. Fischler, R. C. Bolles, "Random Sample Consensus", CACM 1981.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from evedge._validate import check_bool, check_integer, check_positive, check_real

from ._checks import check_events, check_not_before, check_sensor_size
from ._intra_kernels import (_FIT_STRIDE, _NEVER, QUAD_SCRATCH, _fit_windows, _intra_stream, off_as_none,
                             scratch_arrays)
from ._noise_kernels import _AGREE, _BURST_SPAN, _NEWER, _PASSAGE_GAP, N_NOISE
from ._stream_kernels import _pack_lifetimes, _record_columns_into, _record_columns_par_into
from ._tiles import StripStates, check_n_tiles, intra_tiled
from ._workspace import WORKSPACE
from .fill import ARRIVAL, NeighbourFill, check_fill
from .result import LIFETIME_DTYPE, empty_lifetimes
from .protocols import METHODS
from .sae import SurfaceOfActiveEvents

__all__ = ["IntraParams", "IntraPixelLifetime", "NOISE_RULES", "ROBUST", "WindowFit", "estimate_lifetimes",
           "fit_window", "fit_windows", "noise_params", "robust_params"]

#: Kernel arguments (``IntraPixelLifetime.process``'s tuple) passed before the outputs and scratch arrays of
#: :func:`_intra_stream`; those from this index on (added later) come after them.
_N_ARGS = 22

_NO_HALO = np.empty(0, np.int8)  # serial: no strip, no decisions to share
_NO_HALO_LT = np.empty(0)


@dataclass(frozen=True)
class IntraParams:
    """Parameters of the intra-pixel-area RANSAC lifetime estimator.

    Parameters
    ----------
    window_size : int
        N of the N x N SAE window, odd, >= 3 (paper: 5).
    delta_px : float
        Half-size of the intra-pixel area, in [0, 0.5] (paper: 0.25; 0 = plain
        RANSAC; 0.5 = the whole pixel).
    inlier_threshold_us : float
        Absolute part of the inlier threshold on the intra-pixel residual, > 0.
    inlier_threshold_rel : float
        Part of the threshold proportional to the candidate's lifetime, >= 0.
    max_trials : int
        Most RANSAC samples per event, >= 1.
    stop_probability : float
        In (0, 1]; below 1, RANSAC stops once it has found, with this
        probability, a sample of inliers (as scikit-image's ``ransac``); 1 = always
        ``max_trials``.
    min_points : int
        Least points in the kept cluster (current event included) to try, >= 3.
    min_inliers : int
        Least inliers (current event included) for an estimate, >= 3.
    refit_intercept : bool
        Least-squares refit with a free time offset (default) or through the
        current event (the paper's plane contains the current event).
    fallback_all_points : bool
        When the 2-means cluster is degenerate (fewer than ``min_points`` points,
        or all on one line through the current event), run RANSAC on all the
        window's points instead of giving up (default True).
    burst_lifetimes : float
        >= 0. An event continues its pixel's burst (the pixel keeps the burst's
        first time, and the event is fitted at it) when the pixel's previous
        event has the same polarity, an estimate ``L`` and is at most
        ``burst_lifetimes * L`` older (default 1; 0 = the paper's SAE, newest
        event per pixel). See the module notes.
    seed : int
        Seed of the counter-based random stream, 0 <= seed < 2**63.
    per_polarity : bool
        One SAE per polarity (default) or one shared.
    split_gap_ratio : float
        >= 0. Above 0 the current event's cluster is grown by single linkage in
        time instead of 2-means: the nearest remaining window time joins while
        its gap is at most ``split_gap_ratio`` times the largest gap taken so far
        (gaps up to ``inlier_threshold_us`` always join), and whatever the gap
        while the cluster fixes no plane (default 0 = the paper's 2-means). See
        the module notes ("stale levels").
    event_on_plane : float
        >= 0. With ``refit_intercept``: no estimate when the current event is
        farther than ``event_on_plane`` inlier thresholds from the plane fitted
        on its past inliers alone, or when those fix no plane (default 0 = off,
        the paper, whose plane passes through the event; 1 = the event must be
        an inlier of that plane). See the module notes ("noise").
    burst_startup : bool
        With ``burst_lifetimes > 0``: an event whose pixel's previous event (same
        polarity) has no estimate yet is fitted first as a continuation of that
        burst, and kept so when its own lifetime covers the gap; an event without
        estimate inside a burst keeps the burst's lifetime for the next ones
        (default True; False: such events start a new burst, as before). See
        the module notes ("start-up").
    border_px : int
        >= 0. Events closer than this to the sensor's edge, whose window is
        clipped, get no estimate (their fit still sets their pixel's burst
        state); Mueggler et al.'s code skips 2 px. Default 0 (the paper says
        nothing). See the module notes ("border").
    split_jump_check : bool
        With ``split_gap_ratio > 0``: no estimate when the largest time gap the
        linkage cluster took was forced (taken only because the cluster fixed no
        plane yet) and is more than ``split_gap_ratio`` times every other gap it
        took: a jump to a stale level, not a step of the edge's ramp (default
        False, as before). See the module notes ("stale levels").
    stale_fraction : float
        In [0, 1). Above 0, an event that starts a burst ignores the window's
        times older than ``stale_fraction`` of the interval since its pixel's
        previous event of the same polarity (an earlier passage: the same edge
        cannot pass the pixel twice in between); 0.5 is the midpoint. Default 0
        (the paper: every time is a point). Streaming only (a hand-made window
        of :func:`fit_window` has no history). See the module notes ("stale levels").
    startup_reach : float
        >= 0. Above 0, no estimate while the window's history is too short: when
        ``startup_reach`` times the fitted plane's reach in the window (its oldest
        cell is ``half (|a| + |b|)`` before the event) goes back before the first
        event the estimator was given since its last reset (the fit still sets
        the pixel's burst state, as with ``border_px``). Default 0 (the paper).
        Streaming only. 1.5 in the presets (since 2026-12-07). See the module notes ("start-up").
    newer_share_max : float
        In (0, 1]. No estimate when more than this share of the window points
        newer than the fitted plane or on it (its inlier band) are newer than
        it: an edge leaves the pixels it passed on its plane and those ahead
        older; a background event fitted to a steep plane of old points leaves
        the window's recent events above it. Default 1 = off (the paper). See
        the module notes ("noise").
    burst_span_lifetimes : float
        >= 0. With ``burst_lifetimes > 0``: an event continues its pixel's
        burst only when it fired at most this many lifetimes (the previous
        event's estimate) after the burst's first event; otherwise it starts a
        new burst (default 0 = no bound: ``burst_lifetimes`` alone bounds the
        gap to the previous event, so a background event shortly after a burst
        continues it and gets its lifetime). See the module notes ("noise").
    lifetime_agreement : float
        0 or > 1. No estimate when the event's lifetime is more than this
        factor above or below the median of its inlier pixels' own latest
        estimates (when at least 3 of them have one; fewer: kept). Default 0
        = off (the paper). See the module notes ("noise").
    passage_gap : float
        >= 0. No estimate for an event that starts a new burst (it does not
        continue its pixel's burst) when its lifetime is more than this factor
        times the time since the pixel's previous event of the same polarity:
        two passages of an edge closer than one lifetime are closer than one
        pixel, so such a plane joins points of different passages (seen where
        pixels fire on few passages: low contrast, fast edges). Default 0 = off
        (the paper). See the module notes ("passage gap").
    ls_first : float
        In [0, 1]. Least squares first (issue 12): above 0, the plane through
        the current event is first fitted to the whole kept cluster by least
        squares; when every point's residual is within ``ls_first`` times that
        plane's inlier threshold (at 1: every point is an inlier, no hypothesis
        can have more), the result is the refit on all points and no RANSAC
        trial runs; otherwise RANSAC as usual. Default 0.5 (accuracy-neutral
        on the simulator's truth, 1.1-1.2x faster there); 0 = off (the paper's
        RANSAC, the bytes of before). See the module notes ("schedule").
    refine_window : int
        0 (off, the paper) or odd and > ``window_size``. Ring refit: the fit
        (2-means, RANSAC and every rule above) runs on the ``window_size``
        window as usual; its least-squares refit then also takes the points of
        this larger window outside it that lie on the fitted plane (residual,
        less the intra-pixel slack, within the inlier threshold). More points on
        the same plane: less timing noise in the slopes where the plane holds
        (low contrast); the ring itself makes or removes no estimate (the rules
        that read the lifetime may decide a few events differently). 9 in
        :func:`robust_params`. Streaming only (a window of
        :func:`fit_window` has no ring). See the module notes ("ring refit").
    refine_tolerance : float
        In (0, 1]; the ring's points join the refit when their residual (less the
        slack) is within this fraction of the fit's inlier threshold; 1 (the
        default): the fit's threshold itself, the bytes of before this option.
        Below 1, a curved time surface (a rotating edge) lends the refit fewer of
        its outer points. Only with ``refine_window``.
    curvature_f : float
        0 (the default, off: the paper's plane). Otherwise the ring refit also fits
        the quadratic time surface ``dt = a dx + b dy + c dx^2 + d dx dy + e dy^2``
        through the current event (with ``refit_intercept``, plus an offset) on the
        same points, and takes its slopes at the event (``a, b``: lifetime and flow)
        when the F statistic of the three curvature terms exceeds this value: where
        the edge's normal speed changes across the window (rotation, curved edges),
        a plane gives the slopes at the centroid of the past points, not at the
        event. Needs ``refine_window``. See the module notes ("curvature").
    burst_reuse : int
        0: off, every event is fitted (the bytes of before 2026-12-03; the presets
        :func:`robust_params` and :func:`noise_params` kept it off until 2026-12-07, and have 2 since).
        2 (default since 2026-12-03, measured neutral with the defaults). ``k >= 1``,
        with ``burst_lifetimes > 0``: an event that continues its pixel's burst,
        whose burst holds a stored plane, is refitted (``burst_warm_refit``) while
        the burst has stored fewer than ``k`` fits, and from then on takes the
        stored plane (lifetime and flow) with no fit. A burst is one passage of
        the edge, so one lifetime; a reused event runs no fit rule (the
        noise rules, ``split_gap_ratio``), the reporting rules (``border_px``,
        ``startup_reach``) run as always. A fit of ``fallback_all_points`` (RANSAC
        on all points: a degenerate cluster) is never stored, nor one with fewer
        than ``burst_reuse_inliers`` inliers; the burst's next event is then fitted
        again. Speed (issue 12): continuing events are ~half of ``stripes.mat``'s
        and ~3/4 of the simulated ones. Measured neutral against the simulator's
        truth on the quick and full grids (module notes, "burst reuse"): 2 with
        the defaults (estimator 1.3-1.45x / 2.0x cheaper per kept event on
        ``stripes.mat`` / simulated ``shapes_translation``), and 3 with
        ``burst_warm_refit=False`` with both the defaults (1.0x / 1.4x) and
        :func:`noise_params` (1.0x / 1.7x); with :func:`noise_params` the warm
        refits are not neutral (more estimates, more noise given a lifetime), but
        together with ``startup_reach = 1.5`` they meet more of the grid's goals
        (module notes, "presets, 2026-12-07"), so both presets have them.
    burst_warm_refit : bool
        With ``burst_reuse >= 2``: how a burst's events are refitted before its
        plane is reused. True (default): warm, from the stored plane: its inliers
        among the window at the burst's first time (the inlier test of a RANSAC
        candidate) refitted by least squares as a fit's winner, then the rules that
        need no cluster (``min_inliers``, ``event_on_plane``, the noise rules, the
        ring refit); no 2-means, no ``split_gap_ratio``, no trial. A warm refit
        without estimate falls back to the usual fit. False: the usual fit.
    burst_reuse_inliers : int
        With ``burst_reuse >= 1``: a fit (or warm refit) is stored, and counts
        towards ``burst_reuse``, only with at least this many inliers (current
        event included, in the ``window_size`` window: the ring refit's points
        aside). Default 8 (measured with the 5 x 5 window and ``min_inliers = 5``;
        10 is neutral too, a little slower); 0: any (faster, but not neutral on
        the full grid, module notes).
    fill_neighbours : int
        0..8. Above 0, after the estimator, an event it left without estimate gets
        the median lifetime of its recent neighbours' estimates (same polarity
        plane) when at least this many of its 8 neighbours hold one and they agree
        (:mod:`evedge.detector.fill`; filled values never feed the fill's state).
        Default 0 = off (the paper; the bytes of before).
    fill_tolerance : float
        >= 0. The neighbours agree when ``(max - min) <= fill_tolerance * median``
        of their lifetimes (default 0.5).
    fill_agreement : float
        > 0. A neighbour's estimate is recent when it is at most ``fill_agreement``
        times its own lifetime older than the event (default 1.5).
    fill_arrival : float
        >= 0. A recent neighbour counts only when its plane predicts the edge at
        the event's pixel within ``fill_arrival`` times its lifetime of the
        event's time (default 0.5; 0 = off).
    """

    window_size: int = 5
    delta_px: float = 0.25
    inlier_threshold_us: float = 50.0
    inlier_threshold_rel: float = 0.2
    max_trials: int = 20
    stop_probability: float = 0.999
    min_points: int = 5
    min_inliers: int = 5
    refit_intercept: bool = True
    fallback_all_points: bool = True
    burst_lifetimes: float = 1.0
    seed: int = 0
    per_polarity: bool = True
    split_gap_ratio: float = 0.0
    event_on_plane: float = 0.0
    burst_startup: bool = True
    border_px: int = 0
    split_jump_check: bool = False
    stale_fraction: float = 0.0
    startup_reach: float = 0.0
    newer_share_max: float = 1.0
    burst_span_lifetimes: float = 0.0
    lifetime_agreement: float = 0.0
    passage_gap: float = 0.0
    ls_first: float = 0.5
    refine_window: int = 0
    refine_tolerance: float = 1.0
    curvature_f: float = 0.0
    burst_reuse: int = 2
    burst_warm_refit: bool = True
    burst_reuse_inliers: int = 8
    fill_neighbours: int = 0
    fill_tolerance: float = 0.5
    fill_agreement: float = 1.5
    fill_arrival: float = ARRIVAL

    def __post_init__(self) -> None:
        own = "IntraParams"
        check_positive(own, "window_size", self.window_size, integer=True)
        if self.window_size < 3 or self.window_size % 2 == 0:
            raise ValueError(f"{own}.window_size must be odd and >= 3, got {self.window_size}")
        check_positive(own, "delta_px", self.delta_px, allow_zero=True)
        if self.delta_px > 0.5:
            raise ValueError(f"{own}.delta_px must be <= 0.5 (0.5 = the whole pixel), got {self.delta_px}")
        check_positive(own, "inlier_threshold_us", self.inlier_threshold_us)
        check_positive(own, "inlier_threshold_rel", self.inlier_threshold_rel, allow_zero=True)
        check_positive(own, "max_trials", self.max_trials, integer=True)
        check_positive(own, "stop_probability", self.stop_probability)
        if self.stop_probability > 1:
            raise ValueError(f"{own}.stop_probability must be in (0, 1], got {self.stop_probability}")
        for name in ("min_points", "min_inliers"):
            value = getattr(self, name)
            check_positive(own, name, value, integer=True)
            if value < 3:
                raise ValueError(f"{own}.{name} must be >= 3 (a plane needs 3 points), got {value}")
            if value > self.window_size**2:
                raise ValueError(f"{own}.{name} must be <= window_size**2 = {self.window_size**2}, got {value}")
        check_positive(own, "burst_lifetimes", self.burst_lifetimes, allow_zero=True)
        check_positive(own, "split_gap_ratio", self.split_gap_ratio, allow_zero=True)
        check_positive(own, "border_px", self.border_px, integer=True, allow_zero=True)
        check_positive(own, "event_on_plane", self.event_on_plane, allow_zero=True)
        check_positive(own, "startup_reach", self.startup_reach, allow_zero=True)
        check_real(own, "stale_fraction", self.stale_fraction, 0.0, 1.0, low_open=False, high_open=True)
        check_positive(own, "newer_share_max", self.newer_share_max)
        check_positive(own, "burst_span_lifetimes", self.burst_span_lifetimes, allow_zero=True)
        check_positive(own, "lifetime_agreement", self.lifetime_agreement, allow_zero=True)
        check_positive(own, "passage_gap", self.passage_gap, allow_zero=True)
        check_real(own, "ls_first", self.ls_first, 0.0, 1.0, low_open=False, high_open=False)
        if 0 < self.lifetime_agreement <= 1:
            raise ValueError(f"{own}.lifetime_agreement must be 0 (off) or > 1, got {self.lifetime_agreement}")
        if self.newer_share_max > 1:
            raise ValueError(f"{own}.newer_share_max must be in (0, 1] (1 = off), got {self.newer_share_max}")
        check_positive(own, "refine_window", self.refine_window, integer=True, allow_zero=True)
        if self.refine_window and (self.refine_window <= self.window_size or self.refine_window % 2 == 0):
            raise ValueError(f"{own}.refine_window must be 0 (off) or odd and > window_size = {self.window_size}, "
                             f"got {self.refine_window}")
        check_real(own, "refine_tolerance", self.refine_tolerance, 0.0, 1.0, low_open=True, high_open=False)
        check_positive(own, "curvature_f", self.curvature_f, allow_zero=True)
        if self.curvature_f and not self.refine_window:
            raise ValueError(f"{own}.curvature_f = {self.curvature_f} needs the ring refit (refine_window > 0): the "
                             "quadratic is fitted on the ring refit's points")
        check_fill(own, self.fill_neighbours, self.fill_tolerance, self.fill_agreement, self.fill_arrival, prefix="fill_")
        check_positive(own, "seed", self.seed, integer=True, allow_zero=True)
        if self.seed >= 2**63:
            raise ValueError(f"{own}.seed must be < 2**63, got {self.seed}")
        for name in ("per_polarity", "refit_intercept", "fallback_all_points", "burst_startup", "split_jump_check",
                     "burst_warm_refit"):
            check_bool(own, name, getattr(self, name))
        for name in ("burst_reuse", "burst_reuse_inliers"):
            check_integer(own, name, getattr(self, name))
            check_positive(own, name, getattr(self, name), integer=True, allow_zero=True)
        for name in ("window_size", "max_trials", "min_points", "min_inliers", "seed", "border_px",
                     "refine_window", "fill_neighbours"):
            object.__setattr__(self, name, int(getattr(self, name)))
        for name in ("delta_px", "inlier_threshold_us", "inlier_threshold_rel", "stop_probability", "burst_lifetimes",
                     "split_gap_ratio", "event_on_plane", "stale_fraction", "startup_reach", "newer_share_max",
                     "burst_span_lifetimes", "lifetime_agreement", "passage_gap", "ls_first", "fill_tolerance", "fill_agreement",
                     "fill_arrival", "refine_tolerance", "curvature_f"):
            object.__setattr__(self, name, float(getattr(self, name)))


#: The robustness options measured on ``benchmarks/robustness_grid.py`` (module notes), all together.
ROBUST = {"split_gap_ratio": 3.0, "event_on_plane": 1.0, "burst_startup": True, "split_jump_check": True,
          "stale_fraction": 0.5, "startup_reach": 1.5, "refine_window": 9,
          "burst_reuse": 2,  # reach 1.5 and reuse since 2026-12-07 (module notes, "presets, 2026-12-07")
          "curvature_f": 16.0}  # since 2026-12-07, later (module notes, "curvature")


def _preset(base: dict, overrides: dict) -> IntraParams:
    kw = {**base, **overrides}
    if "window_size" in overrides and "refine_window" not in overrides and kw.get("refine_window"):
        # the ring keeps its width (two cells each side of the default fit window) around another one
        kw["refine_window"] = int(overrides["window_size"]) + ROBUST["refine_window"] - IntraParams.window_size
    if "refine_window" in overrides and not overrides["refine_window"] and "curvature_f" not in overrides:
        kw["curvature_f"] = 0.0  # the quadratic is fitted on the ring's points: no ring, no quadratic
    return IntraParams(**kw)


def robust_params(**overrides) -> IntraParams:
    """:class:`IntraParams` with the robustness options on (:data:`ROBUST`), plus any ``overrides``.

    An overridden ``window_size`` keeps the ring refit two cells wide around it
    (``refine_window = window_size + 4``) unless ``refine_window`` is given too;
    ``refine_window = 0`` turns the ring's quadratic (``curvature_f``) off too.

    Examples
    --------
    >>> p = robust_params(seed=3)
    >>> (p.split_gap_ratio, p.event_on_plane, p.burst_startup, p.seed, p.refine_window)
    (3.0, 1.0, True, 3, 9)
    >>> (p.startup_reach, p.burst_reuse, p.curvature_f)
    (1.5, 2, 16.0)
    >>> robust_params(window_size=7).refine_window
    11
    >>> robust_params(refine_window=0).curvature_f
    0.0
    """
    return _preset(ROBUST, overrides)


#: The noise rules measured on ``benchmarks/robustness_grid.py`` (module notes, "noise"), all together.
NOISE_RULES = {"newer_share_max": 0.25, "lifetime_agreement": 2.0, "passage_gap": 1.0}

def noise_params(**overrides) -> IntraParams:
    """:func:`robust_params` with the noise rules on too (:data:`NOISE_RULES`), plus any ``overrides``.

    Examples
    --------
    >>> p = noise_params()
    >>> (p.split_gap_ratio, p.event_on_plane, p.newer_share_max, p.burst_span_lifetimes, p.lifetime_agreement)
    (3.0, 1.0, 0.25, 0.0, 2.0)
    >>> (p.passage_gap, p.startup_reach, p.burst_reuse)
    (1.0, 1.5, 2)
    """
    return _preset({**ROBUST, **NOISE_RULES}, overrides)


def noise_args(params: IntraParams) -> np.ndarray | None:
    """The noise rules' parameters as the kernels take them (one float64 array, :mod:`._noise_kernels`).

    None when every rule is off (the kernels then compile none of them).

    Examples
    --------
    >>> noise_args(IntraParams(newer_share_max=0.25))
    array([0.25, 0.  , 0.  , 0.  ])
    >>> noise_args(IntraParams()) is None
    True
    """
    out = np.zeros(N_NOISE)
    out[_NEWER] = params.newer_share_max
    out[_BURST_SPAN] = params.burst_span_lifetimes
    out[_AGREE] = params.lifetime_agreement
    out[_PASSAGE_GAP] = params.passage_gap
    if (params.newer_share_max == 1.0 and params.burst_span_lifetimes == 0.0 and params.lifetime_agreement == 0.0
            and params.passage_gap == 0.0):
        return None
    return out


def _check_params(params) -> IntraParams:
    if params is None:
        return IntraParams()
    if not isinstance(params, IntraParams):
        raise TypeError(f"params: expected IntraParams, got {type(params).__name__}")
    return params


class IntraPixelLifetime:
    """Streaming lifetime estimator (SAE + 2-means + intra-pixel-area RANSAC).

    Parameters
    ----------
    sensor_size : SensorSize or (width, height)
    params : IntraParams, optional
    n_tiles : int
        Row strips processed in parallel (numba threads; default 1, serial). Any
        value gives the same bytes (:mod:`evedge.detector._tiles`). The strips
        keep their state between chunks (the first chunk fixes where they are
        cut; a chunk then refreshes only their halo rows, not the whole sensor).

    Attributes
    ----------
    sae : SurfaceOfActiveEvents
        The surface the windows are read from. With ``burst_lifetimes > 0`` a
        pixel holds the time of the first event of its current burst, not of
        its newest event (module notes). With strips it is brought up to date
        from them when read.

    Notes
    -----
    :meth:`process` returns one :data:`~evedge.detector.result.LIFETIME_DTYPE`
    row per event of the chunk; feeding the events in any chunking gives the
    same bytes as :func:`estimate_lifetimes` (the burst state, each pixel's
    previous event time, polarity and lifetime, carries across chunks).
    """

    def __init__(self, sensor_size, params: IntraParams | None = None, *, n_tiles: int = 1) -> None:
        self.sensor_size = check_sensor_size(sensor_size)
        self.params = _check_params(params)
        self.n_tiles = check_n_tiles(n_tiles, self.sensor_size.height)
        self._sae: SurfaceOfActiveEvents | None = None  # with its burst arrays, made by reset() or, with strips, when read
        # the serial kernel's, reused by every chunk (the ring refit's quadratic needs a row of QUAD_SCRATCH)
        self._scratch = scratch_arrays(max(self.params.window_size**2, QUAD_SCRATCH if self.params.curvature_f else 0))
        pr = self.params  # the neighbour fill (off: None), run after the kernel on its output
        self._fill = NeighbourFill(self.sensor_size, neighbours=pr.fill_neighbours, tolerance=pr.fill_tolerance,
                                   agreement=pr.fill_agreement, arrival=pr.fill_arrival, per_polarity=pr.per_polarity,
                                   border_px=pr.border_px) if pr.fill_neighbours else None
        self.reset()

    @property
    def sae(self) -> SurfaceOfActiveEvents:
        """The surface of active events (with strips: brought up to date from the strips when read)."""
        self._sync()
        return self._sae

    def _sync(self) -> None:
        """The strips' state (kept between chunks, :class:`~evedge.detector._tiles.StripStates`) into the arrays,
        made first if the stream has not needed them yet."""
        if self._sae is None:
            self._make_arrays()
        if self._strips is not None and self._strips.stale:
            self._strips.store(self._state(), self._prev_fit)
        self._sae._last_time = self._last_time

    def _make_arrays(self) -> None:
        """The SAE and the burst arrays at their initial values (:meth:`reset`)."""
        self._sae = SurfaceOfActiveEvents(self.sensor_size, per_polarity=self.params.per_polarity)
        cells = self._sae.times_us.size
        self._prev_t = np.zeros(cells, dtype=np.int64)
        self._prev_lt = np.full(cells, np.nan)
        self._prev_pol = np.full(cells, -1, dtype=np.int8)
        # burst reuse: the plane (a, b) of each pixel's current burst (NaN = none) and its count of fits; empty = off
        self._prev_fit = np.full(_FIT_STRIDE * cells if self.params.burst_reuse else 0, np.nan)
        self._prev_fit[2::_FIT_STRIDE] = 0.0

    def _state(self):
        """The state arrays as the strips take them, ``(planes, height, width)`` each: SAE, previous time, lifetime
        and polarity."""
        sae = self._sae.times_us
        return (sae, self._prev_t.reshape(sae.shape), self._prev_lt.reshape(sae.shape),
                self._prev_pol.reshape(sae.shape))

    def reset(self) -> None:
        """Clear the SAE, the burst state and the neighbour fill's; restart the event counter of the random stream."""
        # with strips, their own state between chunks, made by the first chunk at the initial values; the arrays
        # (the SAE's, the burst state's) only when read (:meth:`_sync`): a one-shot call never makes them
        self._strips = StripStates() if self.n_tiles > 1 else None
        self._sae = None
        if self._strips is None:
            self._make_arrays()
        self._n_seen = 0
        self._last_time: int | None = None
        self._t_start: int | None = None  # the first event's time (start-up rule)
        if self._fill is not None:
            self._fill.reset()

    def process(self, events: np.ndarray) -> np.ndarray:
        """Estimate lifetime and normal flow of each event of a time-sorted chunk."""
        events = check_events(events, self.sensor_size)
        check_not_before(events, self._last_time)
        n = events.shape[0]
        if n == 0:
            return empty_lifetimes(0)
        out = np.empty(n, dtype=LIFETIME_DTYPE)  # every field is set below
        # the columns and the records out in one numba pass each (with strips: the columns over chunks in
        # parallel); the columns are scratch the workspace keeps mapped between calls (:mod:`._workspace`)
        with WORKSPACE.scope() as take:
            cols = take.empty((4, n), np.int64)
            (_record_columns_par_into if self.n_tiles > 1 else _record_columns_into)(events, cols)
            _pack_lifetimes(*self._estimate(*cols), out)
        return out

    def _estimate(self, x, y, t, p):
        """:meth:`process` on the plain int64 columns of a checked, non-empty chunk.

        (The columns as :func:`~evedge.detector._checks.columns` makes them.)

        Returns ``lt, vx, vy, valid`` (the output's fields as plain arrays) after
        the same state updates as :meth:`process`: for a pipeline that holds the
        columns already (:class:`~evedge.detector.pipeline.Detector`).
        """
        n = x.shape[0]
        if self._last_time is not None and t[0] < self._last_time:
            raise ValueError(f"events: chunk starts at t={int(t[0])} us, before the previous chunk's last event at "
                             f"t={self._last_time} us; chunks must arrive in time order")
        lt = np.empty(n)
        vx = np.empty(n)
        vy = np.empty(n)
        valid = np.empty(n, dtype=bool)
        pr = self.params
        w, h = self.sensor_size.width, self.sensor_size.height
        if self._t_start is None:
            self._t_start = int(t[0])
        # the radius the events read: the ring refit's window when on (the strips' halo), else the fit's
        args = (pr.burst_lifetimes, pr.per_polarity, max(pr.window_size, pr.refine_window) // 2, pr.delta_px,
                pr.inlier_threshold_us,
                pr.inlier_threshold_rel, pr.max_trials, pr.stop_probability, pr.min_points, pr.min_inliers,
                pr.refit_intercept, pr.fallback_all_points, pr.seed, off_as_none(pr.split_gap_ratio),
                off_as_none(pr.event_on_plane), pr.burst_startup, pr.border_px, pr.split_jump_check,
                pr.stale_fraction, self._t_start if pr.startup_reach > 0 else _NEVER,
                pr.startup_reach * (pr.window_size // 2), noise_args(pr),  # options off as None: not compiled
                pr.ls_first,  # from index _N_ARGS on: after the scratch arrays (new arguments at the end)
                pr.window_size // 2 if pr.refine_window else None,  # the ring refit: off as None, not compiled
                pr.burst_reuse, pr.burst_warm_refit, pr.burst_reuse_inliers,  # burst reuse (then its plane array)
                pr.refine_tolerance,  # the ring refit's threshold, after the plane array
                off_as_none(pr.curvature_f))  # the ring refit's quadratic: off as None, not compiled
        if self.n_tiles == 1:
            sae = self._sae.times_us
            burst, per_pol, half = args[:3]
            _intra_stream(x, y, t, p, np.arange(n), 0, self._n_seen, sae.reshape(-1), self._prev_t, self._prev_lt,
                          self._prev_pol, burst, w, h, 0, h, 0, h, _NO_HALO, _NO_HALO_LT, per_pol, half,
                          *args[3:_N_ARGS], lt, vx, vy, valid, *self._scratch, *args[_N_ARGS:-2], self._prev_fit,
                          *args[-2:])
        elif self._sae is None:  # no array read since the reset: the strips (if new) start from the initial values
            shape = (2 if self.params.per_polarity else 1, h, w)
            like = tuple(np.broadcast_to(np.zeros((), d), shape) for d in (np.int64, np.int64, np.float64, np.int8))
            fits = (np.broadcast_to(np.zeros(()), (*shape[:2], _FIT_STRIDE * w)) if self.params.burst_reuse
                    else np.empty(0))
            intra_tiled(x, y, t, p, self._n_seen, like, w, h, self.n_tiles, args, (lt, vx, vy, valid),
                        strips=self._strips, fits=fits, initial=True)
        else:  # (the arrays were read: the strips, if new, start from them)
            intra_tiled(x, y, t, p, self._n_seen, self._state(), w, h, self.n_tiles, args, (lt, vx, vy, valid),
                        strips=self._strips, fits=self._prev_fit)
        if self._fill is not None:  # serial, after the strips: the same bytes for any n_tiles
            self._fill._apply(x, y, t, p, lt, vx, vy, valid)
        self._n_seen += n
        self._last_time = int(t[-1])
        if self._strips is None:  # (with strips: set when the arrays are read, :meth:`_sync`)
            self._sae._last_time = self._last_time
        return lt, vx, vy, valid


def estimate_lifetimes(events: np.ndarray, sensor_size, params: IntraParams | None = None, *,
                       n_tiles: int = 1) -> np.ndarray:
    """One-shot intra-pixel-area lifetime estimation.

    Parameters
    ----------
    events : numpy.ndarray
        Time-sorted events of dtype :data:`evedge.events.EVENT_DTYPE`. Every event
        updates the SAE; filter noise first (:func:`evedge.detector.buffer.filter_events`
        or :func:`evedge.detector.pipeline.detect`).
    sensor_size : SensorSize or (width, height)
    params : IntraParams, optional
    n_tiles : int
        Row strips run in parallel (same bytes for any value; see :class:`IntraPixelLifetime`).

    Returns
    -------
    numpy.ndarray
        :data:`~evedge.detector.result.LIFETIME_DTYPE`, aligned with ``events``.
    """
    return IntraPixelLifetime(sensor_size, params, n_tiles=n_tiles).process(events)


@dataclass(frozen=True)
class WindowFit:
    """Result of :func:`fit_window`.

    Attributes
    ----------
    a_us_per_px, b_us_per_px : float
        Plane slopes ``dt/dx`` and ``dt/dy`` (NaN when not ok).
    inliers : numpy.ndarray
        (N, N) bool: the inlier cells, the centre included (all False when not ok).
    ok : bool
    lifetime_us : float
        ``sqrt(a^2 + b^2)`` or NaN.
    """

    a_us_per_px: float
    b_us_per_px: float
    inliers: np.ndarray
    ok: bool
    lifetime_us: float


def _as_float(values, name: str) -> np.ndarray:
    try:
        return np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise TypeError(f"{name}: expected numbers (timestamps in us, NaN for never-fired pixels): {err}") from None


def _check_windows(windows, name: str) -> np.ndarray:
    w = _as_float(windows, name)
    if w.ndim != 3 or w.shape[1] != w.shape[2]:
        raise ValueError(f"{name}: expected shape (k, N, N), got {np.shape(windows)}")
    side = w.shape[1]
    if side < 3 or side % 2 == 0:
        raise ValueError(f"{name}: window side N must be odd and >= 3, got {side}")
    centre = w[:, side // 2, side // 2]
    if not np.all(np.isfinite(centre)):
        bad = int(np.flatnonzero(~np.isfinite(centre))[0])
        raise ValueError(f"{name}: the centre (current event) of window {bad} is not a finite time")
    if np.any(np.isinf(w)):
        raise ValueError(f"{name}: infinite timestamps (use NaN for never-fired pixels)")
    return w


def fit_windows(windows, params: IntraParams | None = None, *, use_intra: bool = True, seed: int = 0):
    """:func:`fit_window` on a stack of windows in one call (window ``i`` uses stream index ``i``).

    Returns
    -------
    a, b : numpy.ndarray
        (k,) slopes in us/px (NaN when not ok).
    ok : numpy.ndarray
        (k,) bool.
    inliers : numpy.ndarray
        (k, N, N) bool.
    """
    params = _check_params(params)
    w = _check_windows(windows, "windows")
    check_positive("fit_windows", "seed", seed, integer=True, allow_zero=True)
    if seed >= 2**63:  # as IntraParams.seed: the kernel takes an int64
        raise ValueError(f"fit_windows.seed must be < 2**63, got {seed}")
    k, side, _ = w.shape
    if params.min_points > side * side or params.min_inliers > side * side:
        raise ValueError(f"params: min_points/min_inliers exceed the {side}x{side} window")
    a = np.empty(k)
    b = np.empty(k)
    ok = np.empty(k, dtype=bool)
    inl = np.empty(k * side * side, dtype=bool)
    delta = params.delta_px if use_intra else 0.0
    _fit_windows(np.ascontiguousarray(w.reshape(-1)), side, int(seed), 0, delta, params.inlier_threshold_us,
                 params.inlier_threshold_rel, params.max_trials, params.stop_probability, params.min_points,
                 params.min_inliers, params.refit_intercept, params.fallback_all_points, a, b, ok, inl,
                 off_as_none(params.split_gap_ratio), off_as_none(params.event_on_plane), params.split_jump_check,
                 noise_args(params), params.ls_first)
    return a, b, ok, inl.reshape(k, side, side)


def fit_window(window_t_us, params: IntraParams | None = None, *, use_intra: bool = True, seed: int = 0) -> WindowFit:
    """2-means + RANSAC on one hand-made SAE window (the paper's figure 7 study).

    Parameters
    ----------
    window_t_us : array_like
        (N, N) float timestamps in us, NaN where the pixel never fired; the centre
        is the current event. ``N`` need not equal ``params.window_size``.
    params : IntraParams, optional
        Threshold, trials, minimum counts (``window_size`` is ignored).
    use_intra : bool
        False sets ``delta = 0`` (plain RANSAC).
    seed : int
        Seed of the random stream (the window is stream index 0), 0 <= seed < 2**63.

    Returns
    -------
    WindowFit
    """
    w = _as_float(window_t_us, "window_t_us")
    if w.ndim != 2:
        raise ValueError(f"window_t_us: expected an (N, N) array, got shape {w.shape}")
    a, b, ok, inl = fit_windows(w[None], params, use_intra=use_intra, seed=seed)
    lifetime = float(np.hypot(a[0], b[0])) if ok[0] else float("nan")
    return WindowFit(float(a[0]), float(b[0]), inl[0], bool(ok[0]), lifetime)


def _registered(sensor_size, n_tiles: int = 1, **params) -> IntraPixelLifetime:
    """Factory of the method registry: ``IntraPixelLifetime(sensor_size, IntraParams(**params), n_tiles=n_tiles)``."""
    return IntraPixelLifetime(sensor_size, IntraParams(**params), n_tiles=n_tiles)


METHODS.register("intra", _registered, kind="estimator", display_name="proposed (intra-pixel-area)",
                 colour="#d62ad6", params=IntraParams, filter="buffer", extra_params=("n_tiles",))
