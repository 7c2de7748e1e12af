// SPDX-License-Identifier: Apache-2.0
// The frames the page has received, in order, as one growing Float64Array (stride values per
// frame, columns named by the server's hello), plus what the page derives from them frame by
// frame (the cliff's label), and the wake-up latency histogram of every frame received.
// The scene's effects come in the hello as a list (key, number, params, values), each the way
// its schema describes it; the page draws the kinds it knows (surfaces, cliffs) and lists the
// values of every effect, a program's own included, by their column names (KEY1.value).
// Batches arrive as [kind, stride, first sequence number, count, frames...]; a gap in the
// sequence numbers is frames the server dropped for this page (it fell behind).

export const CLIFF_LABELS = ['none', 'supported', 'bridged', 'fallen'];

const HISTOGRAM_BINS = 2000; // 1 us bins up to 2 ms, then overflow

/** What the page draws, from the hello's scene: surfaces (with a colour kind) and cliffs, each
 *  with its number (surface2 is the second [[surface]] of the file). */
export function sceneParts(hello) {
  const effects = hello.scene && Array.isArray(hello.scene.effects) ? hello.scene.effects : [];
  const of = (key) => effects.filter((e) => e.key === key).map((e) => ({ ...e.params, number: e.number }));
  const surfaces = of('surface').map((s) => ({
    ...s,
    kind: s.slippery ? 'slippery' : s.friction ? 'friction' : s.impact ? 'impact' : 'wall',
  }));
  return { effects, surfaces, cliffs: of('cliff') };
}

/** The effects' values among the hello's columns, grouped by effect: [{effect, values:[{name,
 *  column, unit}]}] in column order ("magnet1.distance" is value "distance" of "magnet1"). */
export function effectGroups(hello) {
  const units = {};
  for (const e of sceneParts(hello).effects) {
    (e.values ?? []).forEach((name, k) => {
      units[name] = e.units ? e.units[k] : '';
    });
  }
  const groups = [];
  hello.columns.forEach((name, column) => {
    const dot = name.indexOf('.');
    if (dot <= 0) return;
    const effect = name.slice(0, dot);
    let group = groups.find((g) => g.effect === effect);
    if (!group) {
      group = { effect, values: [] };
      groups.push(group);
    }
    group.values.push({ name: name.slice(dot + 1), column, unit: units[name] ?? '' });
  });
  return groups;
}

export class FrameStore {
  constructor(hello, maxFrames = 1 << 19) {
    this.columns = hello.columns;
    this.stride = hello.columns.length;
    this.col = Object.fromEntries(hello.columns.map((name, i) => [name, i]));
    const parts = sceneParts(hello);
    this.cliff = parts.cliffs.length > 0 ? parts.cliffs[0] : null;
    // The first cliff's state column: from the scene, or from a trace's columns without one.
    this.cliffStateColumn = this.col[`cliff${this.cliff ? this.cliff.number : 1}.state`];
    // The surfaces' impact times ("surface1.impact_t"), with their surface when the scene is known.
    this.impacts = Object.keys(this.col)
      .filter((name) => /^surface\d+\.impact_t$/.test(name))
      .map((name) => ({
        column: this.col[name],
        surface: parts.surfaces.find((sf) => `surface${sf.number}.impact_t` === name) ?? null,
      }));
    this.maxFrames = maxFrames;
    this.data = new Float64Array(this.stride * 4096);
    this.cliffLabel = new Uint8Array(4096);
    this.count = 0;
    this.nextSeq = null; // the sequence number the next frame should have
    this.missing = 0; // frames the server dropped for this page (gaps)
    this.discarded = 0; // oldest frames this page let go of (maxFrames)
    this.faultUnion = 0;
    this.faultTicks = 0;
    this.histogram = new Uint32Array(HISTOGRAM_BINS + 1);
    this.latencyCount = 0;
    this.latencyMax = -Infinity;
    this.computeMax = -Infinity;
    this.#bridging = false;
  }

  #bridging;

  /** Appends one binary batch; returns the number of frames added. */
  addBatch(buffer) {
    const values = new Float64Array(buffer);
    const stride = values[1];
    const firstSeq = values[2];
    const n = values[3];
    if (stride !== this.stride || values.length !== 4 + n * stride) {
      throw new Error(`malformed batch: stride ${stride} (expected ${this.stride}), ${values.length} values for ${n} frames`);
    }
    if (this.nextSeq !== null && firstSeq > this.nextSeq) this.missing += firstSeq - this.nextSeq;
    this.nextSeq = firstSeq + n;
    this.#reserve(this.count + n);
    this.data.set(values.subarray(4), this.count * this.stride);
    for (let i = this.count; i < this.count + n; ++i) this.#derive(i);
    this.count += n;
    return n;
  }

  #reserve(frames) {
    if (frames > this.maxFrames) {
      // Let go of the oldest half: memory stays bounded on a run that goes on for hours.
      const drop = Math.max(frames - this.maxFrames, this.count >> 1);
      this.data.copyWithin(0, drop * this.stride, this.count * this.stride);
      this.cliffLabel.copyWithin(0, drop, this.count);
      this.count -= drop;
      this.discarded += drop;
      frames -= drop;
    }
    if (frames * this.stride <= this.data.length) return;
    let capacity = this.data.length / this.stride;
    while (capacity < frames) capacity *= 2;
    const data = new Float64Array(capacity * this.stride);
    data.set(this.data.subarray(0, this.count * this.stride));
    this.data = data;
    const labels = new Uint8Array(capacity);
    labels.set(this.cliffLabel.subarray(0, this.count));
    this.cliffLabel = labels;
  }

  /** The cliff's label at frame i, from its state and the frames before it:
   *  fallen while the cliff has dropped the HIP; bridged once the HIP has been over the gap
   *  held up (and until it falls); supported on the ground before that; none without a cliff. */
  #derive(i) {
    const c = this.col;
    const row = i * this.stride;
    const d = this.data;
    const faults = d[row + c.faults];
    if (faults > 0) {
      this.faultUnion |= faults;
      this.faultTicks += 1;
    }
    const latency = d[row + c.wake_latency_us];
    if (Number.isFinite(latency)) {
      const bin = Math.min(HISTOGRAM_BINS, Math.max(0, Math.floor(latency)));
      this.histogram[bin] += 1;
      this.latencyCount += 1;
      this.latencyMax = Math.max(this.latencyMax, latency);
    }
    const compute = d[row + c.compute_us];
    if (Number.isFinite(compute)) this.computeMax = Math.max(this.computeMax, compute);

    const state = this.cliffStateColumn === undefined ? NaN : d[row + this.cliffStateColumn];
    let label = 0;
    if (state === 1) {
      label = 3;
      this.#bridging = false;
    } else if (state === 0) {
      if (this.cliff && this.overGap(d[row + c.x], d[row + c.y], d[row + c.z])) this.#bridging = true;
      label = this.#bridging ? 2 : 1;
    } else if (Number.isNaN(state) && i > 0) {
      label = this.cliffLabel[i - 1]; // a fault tick has no diagnostics: keep the last label
    }
    this.cliffLabel[i] = label;
  }

  /** The HIP is over the cliff's gap strip (along its axis, from its point). */
  overGap(x, y, z) {
    const cl = this.cliff;
    const a = cl.axis;
    const p = cl.point;
    const s = (x - p[0]) * a[0] + (y - p[1]) * a[1] + (z - p[2]) * a[2];
    return s >= cl.gap_min && s <= cl.gap_max;
  }

  get(i, name) {
    return this.data[i * this.stride + this.col[name]];
  }

  /** The impact transient running at frame i: {t (seconds since its trigger), surface} or null. */
  runningImpact(i) {
    for (const impact of this.impacts) {
      const t = this.data[i * this.stride + impact.column];
      if (Number.isFinite(t)) return { t, surface: impact.surface };
    }
    return null;
  }

  time(i) {
    return this.data[i * this.stride];
  }

  /** Index of the last frame at or before time t (0 if none). */
  indexAt(t) {
    let lo = 0;
    let hi = this.count - 1;
    if (hi < 0) return 0;
    if (t >= this.time(hi)) return hi;
    while (lo < hi) {
      const mid = (lo + hi + 1) >> 1;
      if (this.time(mid) <= t) lo = mid;
      else hi = mid - 1;
    }
    return lo;
  }

  /** Latency percentile [us] over the histogram (q in 0..1). */
  latencyPercentile(q) {
    if (this.latencyCount === 0) return NaN;
    const target = q * this.latencyCount;
    let seen = 0;
    for (let b = 0; b <= HISTOGRAM_BINS; ++b) {
      seen += this.histogram[b];
      if (seen >= target) return b;
    }
    return HISTOGRAM_BINS;
  }
}
