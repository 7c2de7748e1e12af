// SPDX-License-Identifier: Apache-2.0
// Live plots of position and force against time, as in the paper's figure 3, on a 2D canvas:
// each series is reduced to its minimum and maximum per pixel column, so a 1 kHz stream costs
// the same to draw as a slow one. And the wake-up latency histogram of the loop.

const SERIES = [
  { plot: 0, name: 'x', label: 'x', colour: '#5a6fb0', scale: 1000 },
  { plot: 0, name: 'z', label: 'z', colour: '#c0392b', scale: 1000 },
  { plot: 1, name: 'fx', label: 'Fx', colour: '#5a6fb0', scale: 1 },
  { plot: 1, name: 'fz', label: 'Fz', colour: '#c0392b', scale: 1 },
];
const TITLES = ['HIP position [mm]', 'force [N]'];

/** A world's plots (the hello's `world`): each device's HIP x and its commanded force's
 *  magnitude, one trace a device in its colour, named. */
export function worldSeries(world, colours) {
  const series = [];
  world.devices.forEach((name, k) => {
    const colour = colours[k % colours.length];
    series.push({ plot: 0, name: `${name}.x`, label: `${name} x`, colour, scale: 1000 });
    series.push({
      plot: 1,
      name: `${name}.fx`,
      label: `${name} |F|`,
      colour,
      scale: 1,
      value: (store, i) => Math.hypot(store.get(i, `${name}.fx`), store.get(i, `${name}.fy`), store.get(i, `${name}.fz`)),
    });
  });
  return { series, titles: ['HIP x, world frame [mm]', 'commanded force |F| [N]'] };
}

function niceRange(lo, hi) {
  if (!Number.isFinite(lo) || !Number.isFinite(hi)) return [-1, 1];
  if (hi - lo < 1e-9) {
    lo -= 1;
    hi += 1;
  }
  const pad = (hi - lo) * 0.08;
  return [lo - pad, hi + pad];
}

export class Plots {
  constructor(canvas) {
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    this.window = 4; // seconds shown
    this.series = SERIES;
    this.titles = TITLES;
  }

  /** Other series (a world's: worldSeries). */
  setSeries({ series, titles }) {
    this.series = series;
    this.titles = titles;
  }

  resize() {
    const ratio = Math.min(window.devicePixelRatio || 1, 2);
    const w = Math.max(1, this.canvas.clientWidth);
    const h = Math.max(1, this.canvas.clientHeight);
    if (this.canvas.width !== Math.round(w * ratio) || this.canvas.height !== Math.round(h * ratio)) {
      this.canvas.width = Math.round(w * ratio);
      this.canvas.height = Math.round(h * ratio);
    }
    this.ratio = ratio;
    this.w = w;
    this.h = h;
  }

  /** Draws the window ending at frame `cursor` (live), or centred on it (recording). */
  draw(store, cursor, centred) {
    this.resize();
    const ctx = this.ctx;
    ctx.setTransform(this.ratio, 0, 0, this.ratio, 0, 0);
    ctx.clearRect(0, 0, this.w, this.h);
    ctx.font = '11px system-ui, sans-serif';
    if (store.count === 0) return;
    const tc = store.time(cursor);
    const first = store.time(0);
    const last = store.time(store.count - 1);
    // A recording shorter than the window is shown whole; a longer one around the cursor.
    const span = centred ? Math.min(this.window, Math.max(last - first, 1e-3)) : this.window;
    const t1 = centred ? Math.min(Math.max(tc + span / 2, first + span), last) : tc;
    const t0 = Math.max(first, t1 - span);
    const i0 = store.indexAt(t0);
    const i1 = centred ? store.indexAt(t1) : cursor;
    const left = 52;
    const right = 12;
    const plotH = (this.h - 36) / 2;
    const width = this.w - left - right;
    for (let p = 0; p < 2; ++p) {
      const top = 8 + p * (plotH + 14);
      const series = this.series.filter((s) => s.plot === p);
      const columns = series.map(() => ({ min: new Float64Array(width).fill(Infinity), max: new Float64Array(width).fill(-Infinity) }));
      let lo = Infinity;
      let hi = -Infinity;
      for (let i = i0; i <= i1; ++i) {
        const px = Math.floor(((store.time(i) - t0) / span) * (width - 1));
        if (px < 0 || px >= width) continue;
        series.forEach((s, k) => {
          const v = (s.value ? s.value(store, i) : store.get(i, s.name)) * s.scale;
          if (!Number.isFinite(v)) return;
          const col = columns[k];
          if (v < col.min[px]) col.min[px] = v;
          if (v > col.max[px]) col.max[px] = v;
          if (v < lo) lo = v;
          if (v > hi) hi = v;
        });
      }
      const [ylo, yhi] = niceRange(Math.min(lo, 0), Math.max(hi, 0));
      const yOf = (v) => top + plotH - ((v - ylo) / (yhi - ylo)) * plotH;
      ctx.strokeStyle = '#ccc';
      ctx.lineWidth = 1;
      ctx.strokeRect(left, top, width, plotH);
      ctx.strokeStyle = '#999';
      ctx.setLineDash([4, 3]);
      ctx.beginPath();
      ctx.moveTo(left, yOf(0));
      ctx.lineTo(left + width, yOf(0));
      ctx.stroke();
      ctx.setLineDash([]);
      ctx.fillStyle = '#444';
      ctx.fillText(this.titles[p], left + 4, top + 12);
      ctx.fillText(yhi.toPrecision(3), 2, top + 10);
      ctx.fillText(ylo.toPrecision(3), 2, top + plotH);
      // Labels left to right, ending at the plot's right edge (a world's names are longer).
      const labelAt = [];
      let labelX = left + width - 6;
      for (let k = series.length - 1; k >= 0; --k) {
        labelX -= ctx.measureText(series[k].label).width + 8;
        labelAt[k] = labelX;
      }
      series.forEach((s, k) => {
        const col = columns[k];
        ctx.strokeStyle = s.colour;
        ctx.lineWidth = 1.5;
        ctx.beginPath();
        let started = false;
        for (let px = 0; px < width; ++px) {
          if (col.min[px] === Infinity) continue;
          const x = left + px;
          if (!started) {
            ctx.moveTo(x, yOf(col.min[px]));
            started = true;
          } else {
            ctx.lineTo(x, yOf(col.min[px]));
          }
          if (col.max[px] !== col.min[px]) ctx.lineTo(x, yOf(col.max[px]));
        }
        ctx.stroke();
        ctx.fillStyle = s.colour;
        ctx.fillText(s.label, this.series === SERIES ? left + width - 40 + k * 20 : labelAt[k], top + 12);
      });
      if (centred) {
        const x = left + ((tc - t0) / span) * (width - 1);
        ctx.strokeStyle = '#222';
        ctx.beginPath();
        ctx.moveTo(x, top);
        ctx.lineTo(x, top + plotH);
        ctx.stroke();
      }
    }
    ctx.fillStyle = '#444';
    ctx.fillText(`${t0.toFixed(2)} s`, left, this.h - 4);
    const end = `${(t0 + span).toFixed(2)} s`;
    ctx.fillText(end, left + width - ctx.measureText(end).width, this.h - 4);
  }
}

/** The wake-up latency histogram [us] of every frame received, log-scaled counts. */
export function drawHistogram(canvas, store) {
  const ctx = canvas.getContext('2d');
  const w = canvas.width;
  const h = canvas.height;
  ctx.clearRect(0, 0, w, h);
  ctx.font = '10px system-ui, sans-serif';
  canvas.hidden = store.latencyCount === 0;
  if (store.latencyCount === 0) return;
  const top = Math.max(20, Math.ceil(store.latencyPercentile(0.999) * 1.25));
  const bins = 60;
  const width = top / bins;
  const counts = new Float64Array(bins + 1);
  for (let b = 0; b < store.histogram.length; ++b) {
    const n = store.histogram[b];
    if (n === 0) continue;
    counts[Math.min(bins, Math.floor(b / width))] += n;
  }
  const maxLog = Math.log10(1 + Math.max(...counts));
  const bw = (w - 10) / (bins + 1);
  for (let k = 0; k <= bins; ++k) {
    const bh = maxLog > 0 ? (Math.log10(1 + counts[k]) / maxLog) * (h - 24) : 0;
    ctx.fillStyle = k === bins ? '#c0392b' : '#5a6fb0';
    ctx.fillRect(5 + k * bw, h - 14 - bh, Math.max(1, bw - 1), bh);
  }
  ctx.fillStyle = '#444';
  ctx.fillText('0', 5, h - 2);
  const label = `${top.toFixed(0)} us`;
  ctx.fillText(label, w - 5 - ctx.measureText(label).width - bw, h - 2);
  ctx.fillText('wake-up latency (log count)', 5, 10);
}
