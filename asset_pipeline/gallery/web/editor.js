// pact gallery: the mask editor (ES module; no three.js).
//
// Served by `pact gallery OUT --serve` (asset_pipeline/gallery/server.py), every card of an
// asset converted from a photo has an "edit mask" button. It opens the photo at its full
// size with the current part mask over it (GET /api/editor/asset, /photo, /mask). Tools:
// a rectangle, a polygon (click the corners; double-click or Enter closes it, Esc drops
// it, Backspace takes back a corner), which id a drawn region gets ("paint as": the base,
// a part, a new part, or the background to erase), undo (Ctrl+Z), a motion per movable
// part and the category. "Save and convert" sends the mask (a PNG of part ids at the
// photo's size: 0 background, 1 base, 2..K parts, ids made consecutive) and the hints to
// POST /api/editor/save; the server checks them, writes <name>.mask.png and <name>.json
// beside the photo and re-converts the item. The page polls /api/editor/status and, when
// the job is over, replaces the card with the new one from index.html (new renders, a new
// 3D view: viewer.js listens for `gallery-card-replaced`).
//
// State for scripts and tests: #mask-editor[data-state] (loading, ready, saving, error);
// each card's data-edit-state (converting, done, failed); <body data-editor="on|off|file">.

const API = 'api/editor';
const POLL_MS = 700;
let info = null; // GET /api/editor: motions, categories, palette
let current = null; // the open Editor

function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === 'class') e.className = v;
    else if (k === 'text') e.textContent = v;
    else if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
    else if (v !== undefined && v !== null && v !== false) e.setAttribute(k, v === true ? '' : v);
  }
  for (const c of children) if (c !== null && c !== undefined) e.append(c);
  return e;
}

async function getJSON(url) {
  const res = await fetch(url, { cache: 'no-store' });
  let doc = null;
  try {
    doc = await res.json();
  } catch {
    doc = null;
  }
  if (!res.ok) throw new Error((doc && doc.error) || `${url}: HTTP ${res.status}`);
  return doc;
}

function loadImage(url) {
  return new Promise((resolve, reject) => {
    const img = new Image();
    img.onload = () => resolve(img);
    img.onerror = () => reject(new Error(`${url}: not loaded`));
    img.src = url;
  });
}

function percent(c) {
  return `${Math.round(Number(c) * 100)}% sure`;
}

function share(n, total) {
  const p = (100 * n) / total;
  return p >= 0.1 ? `${p.toFixed(1)}% of the photo` : `${n} px`;
}

function cardOf(id) {
  return document.getElementById(id);
}

// ------------------------------------------------------------------ raster operations

// Fill the pixels whose centres lie inside the polygon (even-odd), as id; returns the
// changed bounding box or null.
function polygonSpans(points, W, H, visit) {
  let y0 = Infinity;
  let y1 = -Infinity;
  for (const [, y] of points) {
    y0 = Math.min(y0, y);
    y1 = Math.max(y1, y);
  }
  const rowStart = Math.max(0, Math.floor(y0));
  const rowEnd = Math.min(H - 1, Math.ceil(y1));
  for (let row = rowStart; row <= rowEnd; row++) {
    const yc = row + 0.5;
    const xs = [];
    for (let i = 0; i < points.length; i++) {
      const [ax, ay] = points[i];
      const [bx, by] = points[(i + 1) % points.length];
      if ((ay <= yc && by > yc) || (by <= yc && ay > yc)) xs.push(ax + ((yc - ay) / (by - ay)) * (bx - ax));
    }
    xs.sort((a, b) => a - b);
    for (let k = 0; k + 1 < xs.length; k += 2) {
      const from = Math.max(0, Math.ceil(xs[k] - 0.5));
      const to = Math.min(W - 1, Math.floor(xs[k + 1] - 0.5));
      if (to >= from) visit(row, from, to);
    }
  }
}

class Editor {
  constructor(card, state) {
    this.card = card;
    this.state = state;
    this.id = state.id;
    this.W = state.width;
    this.H = state.height;
    this.mask = new Uint8Array(this.W * this.H);
    this.undoStack = [];
    this.tool = 'rect';
    this.paint = 1;
    this.draft = []; // polygon corners so far
    this.hints = state.hints || {};
    const parsed = this.hints.parsed || {};
    this.parsed = parsed;
    // per mask id as opened (and ids drawn here): {motion, set}
    this.motions = new Map();
    for (const [k, v] of Object.entries(this.hints.parts || {})) {
      this.motions.set(Number(k), { motion: v.motion || '', set: false });
    }
    this.opened = new Set(state.ids);
    this.nextId = Math.max(1, ...state.ids) + 1;
    this.category = state.category;
    this.categorySet = false;
    this.maskConfirmed = false;
    this.edited = false;
    this.build();
  }

  // ---- the page
  build() {
    const stage = el('div', { class: 'me-stage' });
    this.photoCanvas = el('canvas', { class: 'me-photo', width: this.W, height: this.H });
    this.maskCanvas = el('canvas', { class: 'me-mask', width: this.W, height: this.H });
    this.svg = document.createElementNS('http://www.w3.org/2000/svg', 'svg');
    this.svg.setAttribute('viewBox', `0 0 ${this.W} ${this.H}`);
    this.svg.setAttribute('preserveAspectRatio', 'none');
    this.wrap = el('div', { class: 'me-wrap' }, this.photoCanvas, this.maskCanvas, this.svg);
    stage.append(this.wrap, el('div', { class: 'me-hint', text: '' }));
    this.hint = stage.querySelector('.me-hint');

    const tools = el('div', { class: 'me-tools' });
    this.toolButtons = {};
    for (const [name, label, key] of [
      ['rect', 'rectangle', 'R'],
      ['poly', 'polygon', 'P'],
    ]) {
      const b = el('button', { type: 'button', 'data-tool': name, title: `${label} (${key})`, text: label });
      b.addEventListener('click', () => this.setTool(name));
      this.toolButtons[name] = b;
      tools.append(b);
    }
    this.paintSelect = el('select', { class: 'me-paint', title: 'the id a drawn region gets' });
    this.paintSelect.addEventListener('change', () => this.setPaint(this.paintSelect.value));
    const erase = el('button', { type: 'button', class: 'me-erase', title: 'paint background (E)', text: 'erase' });
    erase.addEventListener('click', () => this.setPaint('0'));
    this.eraseButton = erase;
    const undo = el('button', { type: 'button', class: 'me-undo', title: 'undo (Ctrl+Z)', text: 'undo' });
    undo.addEventListener('click', () => this.undo());
    this.undoButton = undo;
    const opacity = el('input', { type: 'range', min: 0, max: 1, step: 0.05, value: 0.55, title: 'mask opacity' });
    opacity.addEventListener('input', () => (this.maskCanvas.style.opacity = opacity.value));
    this.maskCanvas.style.opacity = opacity.value;
    tools.append(
      el('label', {}, 'paint as ', this.paintSelect),
      erase,
      undo,
      el('label', { title: 'mask opacity' }, 'mask ', opacity),
    );

    this.categorySelect = el('select', { class: 'me-category' });
    for (const [value, label] of info.categories) this.categorySelect.append(el('option', { value, text: label }));
    this.categorySelect.value = this.category;
    this.categorySelect.addEventListener('change', () => {
      this.categorySet = true;
      this.renderSources();
    });
    this.categorySource = el('div', { class: 'src me-category-src' });

    this.partsBox = el('div', { class: 'me-parts' });
    this.maskSource = el('div', { class: 'src me-mask-src' });
    this.status = el('div', { class: 'me-status', role: 'status' });
    this.saveButton = el('button', { type: 'button', class: 'save', text: 'Save and convert' });
    this.saveButton.addEventListener('click', () => this.save());
    const close = el('button', { type: 'button', class: 'close', text: 'close without saving' });
    close.addEventListener('click', () => this.close());

    const notes = [...(this.state.mask_notes || [])];
    if (this.state.hints_error) notes.push(this.state.hints_error);
    const panel = el(
      'div',
      { class: 'me-panel' },
      el('h3', { text: `edit mask: ${this.id}` }),
      el('div', {
        class: 'sub',
        text: `${this.state.photo_name} · ${this.W} × ${this.H} px · generator ${this.state.generator}`,
      }),
      el('fieldset', {}, el('legend', { text: 'draw' }), tools),
      el('fieldset', {}, el('legend', { text: 'category' }), this.categorySelect, this.categorySource),
      el('fieldset', {}, el('legend', { text: 'parts and how they move' }), this.partsBox, this.maskSource),
      notes.length ? el('div', { class: 'me-status error', text: notes.join('\n') }) : null,
      el('div', { class: 'me-actions' }, this.saveButton, close),
      this.status,
      el('div', {
        class: 'sub',
        text:
          'Saving writes two files beside the photo, its .mask.png and its .json hints, ' +
          'then converts the photo again into this gallery.',
      }),
    );
    this.root = el('div', { id: 'mask-editor', 'data-state': 'loading', 'data-asset': this.id }, stage, panel);
    this.keys = (ev) => this.onKey(ev); // on document: focus may be anywhere (a disabled button)
    this.root.tabIndex = -1;
    this.bindPointer();
    this.ro = new ResizeObserver(() => this.fit());
    this.ro.observe(stage);
    this.stage = stage;
  }

  async open() {
    document.body.append(this.root);
    document.body.classList.add('has-editor');
    document.addEventListener('keydown', this.keys);
    this.root.focus();
    const q = `id=${encodeURIComponent(this.id)}`;
    const [photo, mask] = await Promise.all([
      loadImage(`${API}/photo?${q}`),
      this.state.has_mask ? loadImage(`${API}/mask?${q}`) : Promise.resolve(null),
    ]);
    this.photoCanvas.getContext('2d').drawImage(photo, 0, 0);
    if (mask) {
      const c = document.createElement('canvas');
      c.width = this.W;
      c.height = this.H;
      const ctx = c.getContext('2d', { willReadFrequently: true });
      ctx.drawImage(mask, 0, 0);
      const px = ctx.getImageData(0, 0, this.W, this.H).data;
      for (let i = 0; i < this.mask.length; i++) this.mask[i] = px[4 * i];
    }
    this.overlay = this.maskCanvas.getContext('2d').createImageData(this.W, this.H);
    this.redraw(0, 0, this.W, this.H);
    this.setTool('rect');
    this.refreshParts();
    this.setPaint('1');
    this.fit();
    this.root.dataset.state = 'ready';
  }

  close() {
    document.removeEventListener('keydown', this.keys);
    this.ro.disconnect();
    this.root.remove();
    document.body.classList.remove('has-editor');
    if (current === this) current = null;
  }

  fit() {
    const r = this.stage.getBoundingClientRect();
    const s = Math.min((r.width - 24) / this.W, (r.height - 40) / this.H);
    const scale = Math.max(s, 0.05);
    this.photoCanvas.style.width = `${Math.round(this.W * scale)}px`;
    this.photoCanvas.style.height = `${Math.round(this.H * scale)}px`;
  }

  // ---- the mask
  colour(id) {
    const p = info.palette;
    return p[Math.min(id, p.length - 1)];
  }

  redraw(x0, y0, x1, y1) {
    const d = this.overlay.data;
    for (let y = y0; y < y1; y++) {
      for (let x = x0; x < x1; x++) {
        const i = y * this.W + x;
        const id = this.mask[i];
        const o = 4 * i;
        if (id === 0) {
          d[o + 3] = 0;
          continue;
        }
        const [r, g, b] = this.colour(id);
        d[o] = r;
        d[o + 1] = g;
        d[o + 2] = b;
        d[o + 3] = 255;
      }
    }
    this.maskCanvas.getContext('2d').putImageData(this.overlay, 0, 0, x0, y0, x1 - x0, y1 - y0);
  }

  counts() {
    const n = new Array(256).fill(0);
    for (let i = 0; i < this.mask.length; i++) n[this.mask[i]]++;
    return n;
  }

  // Paint `id` over the pixels `spans` (row, from, to inclusive) names, undoably.
  apply(id, bbox, spans) {
    const [x0, y0, x1, y1] = bbox;
    if (x1 <= x0 || y1 <= y0) return false;
    const w = x1 - x0;
    const before = new Uint8Array(w * (y1 - y0));
    for (let y = y0; y < y1; y++) before.set(this.mask.subarray(y * this.W + x0, y * this.W + x1), (y - y0) * w);
    let changed = 0;
    spans((row, from, to) => {
      for (let x = from; x <= to; x++) {
        const i = row * this.W + x;
        if (this.mask[i] !== id) {
          this.mask[i] = id;
          changed++;
        }
      }
    });
    if (!changed) return false;
    const newPart = id >= this.nextId;
    this.undoStack.push({ bbox, before, nextId: this.nextId });
    if (newPart) this.nextId = id + 1;
    this.edited = true;
    this.redraw(x0, y0, x1, y1);
    this.refreshParts();
    if (newPart) this.setPaint(String(id));
    return true;
  }

  fillRect(a, b) {
    const x0 = Math.max(0, Math.round(Math.min(a[0], b[0])));
    const x1 = Math.min(this.W, Math.round(Math.max(a[0], b[0])));
    const y0 = Math.max(0, Math.round(Math.min(a[1], b[1])));
    const y1 = Math.min(this.H, Math.round(Math.max(a[1], b[1])));
    this.apply(this.paintId(), [x0, y0, x1, y1], (visit) => {
      for (let y = y0; y < y1; y++) visit(y, x0, x1 - 1);
    });
  }

  fillPolygon(points) {
    if (points.length < 3) return;
    const xs = points.map((p) => p[0]);
    const ys = points.map((p) => p[1]);
    const bbox = [
      Math.max(0, Math.floor(Math.min(...xs))),
      Math.max(0, Math.floor(Math.min(...ys))),
      Math.min(this.W, Math.ceil(Math.max(...xs)) + 1),
      Math.min(this.H, Math.ceil(Math.max(...ys)) + 1),
    ];
    this.apply(this.paintId(), bbox, (visit) => polygonSpans(points, this.W, this.H, visit));
  }

  undo() {
    const step = this.undoStack.pop();
    if (!step) return;
    const [x0, y0, x1, y1] = step.bbox;
    const w = x1 - x0;
    for (let y = y0; y < y1; y++) this.mask.set(step.before.subarray((y - y0) * w, (y - y0 + 1) * w), y * this.W + x0);
    for (const id of [...this.motions.keys()]) if (id >= step.nextId) this.motions.delete(id);
    this.nextId = step.nextId;
    this.edited = this.undoStack.length > 0;
    this.redraw(x0, y0, x1, y1);
    this.refreshParts();
  }

  // ---- tools
  setTool(name) {
    this.tool = name;
    this.cancelDraft();
    for (const [k, b] of Object.entries(this.toolButtons)) b.classList.toggle('on', k === name);
    this.hint.textContent =
      name === 'rect'
        ? 'rectangle: drag over the photo'
        : 'polygon: click the corners; double-click or Enter closes it, Esc drops it, Backspace takes one back';
  }

  paintId() {
    return Number(this.paintSelect.value);
  }

  setPaint(value) {
    this.refreshPaintOptions();
    this.paintSelect.value = value;
    if (this.paintSelect.value !== value) this.paintSelect.value = '1';
    this.eraseButton.classList.toggle('on', this.paintSelect.value === '0');
  }

  partName(id) {
    if (id === 1) return 'base';
    const m = this.motions.get(id);
    const word = m && m.motion ? info.motions.find(([k]) => k === m.motion)?.[1] : null;
    return `part ${id}${word ? ` · ${word.split(' (')[0]}` : ''}`;
  }

  refreshPaintOptions() {
    const keep = this.paintSelect.value;
    const present = this.presentIds();
    this.paintSelect.replaceChildren();
    this.paintSelect.append(el('option', { value: '1', text: 'base (1)' }));
    for (const id of present) if (id >= 2) this.paintSelect.append(el('option', { value: String(id), text: this.partName(id) }));
    if (this.nextId <= info.max_part_id) {
      this.paintSelect.append(el('option', { value: String(this.nextId), text: `new part (${this.nextId})` }));
    }
    this.paintSelect.append(el('option', { value: '0', text: 'background (erase)' }));
    if (keep) this.paintSelect.value = keep;
    if (!this.paintSelect.value) this.paintSelect.value = '1'; // never erase by surprise
  }

  presentIds() {
    const n = this.counts();
    const ids = [];
    for (let i = 1; i < 256; i++) if (n[i]) ids.push(i);
    return ids;
  }

  // ---- parts, motions, category
  refreshParts() {
    const n = this.counts();
    const total = this.W * this.H;
    this.partsBox.replaceChildren();
    for (const id of this.presentIds()) {
      const [r, g, b] = this.colour(id);
      const row = el(
        'div',
        { class: 'me-part', 'data-part': String(id) },
        el('span', { class: 'sw', style: `background:rgb(${r},${g},${b})` }),
        el('span', { text: `${id === 1 ? 'base (1)' : `part ${id}`} · ${share(n[id], total)}` }),
      );
      if (id >= 2) {
        const m = this.motions.get(id) || { motion: '', set: false };
        this.motions.set(id, m);
        const sel = el('select', { class: 'me-motion', 'data-part': String(id), title: 'how this part moves' });
        sel.append(el('option', { value: '', text: 'let the generator decide' }));
        for (const [value, label] of info.motions) sel.append(el('option', { value, text: label }));
        sel.value = m.motion;
        sel.addEventListener('change', () => {
          m.motion = sel.value;
          m.set = true;
          this.refreshParts();
          this.refreshPaintOptions();
        });
        row.append(sel);
        const conf = this.parsedPart(id);
        if (m.set) row.append(el('div', { class: 'src', text: 'set by you' }));
        else if (conf !== null && m.motion) {
          const ok = el('button', { type: 'button', class: 'confirm', text: 'confirm' });
          ok.addEventListener('click', () => {
            m.set = true;
            this.refreshParts();
          });
          row.append(el('div', { class: 'src' }, `the photo parser's guess, ${percent(conf)}`, ok));
        }
      }
      this.partsBox.append(row);
    }
    if (!this.presentIds().length) this.partsBox.append(el('div', { class: 'src', text: 'no parts yet: paint the base first' }));
    this.refreshPaintOptions();
    this.renderSources();
  }

  parsedPart(id) {
    // the parser's confidence in part `id`'s motion: only for a part as it was opened
    if (!this.opened.has(id) || !this.parsed.parts) return null;
    const c = this.parsed.parts[String(id)];
    return c === undefined ? null : c;
  }

  renderSources() {
    this.categorySource.replaceChildren();
    if (this.categorySet) this.categorySource.append('set by you');
    else if (this.parsed.category !== undefined) {
      const ok = el('button', { type: 'button', class: 'confirm', text: 'confirm' });
      ok.addEventListener('click', () => {
        this.categorySet = true;
        this.renderSources();
      });
      this.categorySource.append(`the photo parser's guess, ${percent(this.parsed.category)}`, ok);
    }
    this.maskSource.replaceChildren();
    if (this.edited) this.maskSource.append('mask edited by you');
    else if (this.parsed.mask !== undefined) {
      const box = el('input', { type: 'checkbox', class: 'me-mask-confirm' });
      box.checked = this.maskConfirmed;
      box.addEventListener('change', () => (this.maskConfirmed = box.checked));
      this.maskSource.append(
        `mask from the photo parser, ${percent(this.parsed.mask)} `,
        el('label', {}, box, ' it is right'),
      );
    } else if (!this.state.has_mask) this.maskSource.append('this photo had no mask: paint the base (1) and its parts');
  }

  // ---- pointer and keys
  toImage(ev) {
    const r = this.wrap.getBoundingClientRect();
    return [((ev.clientX - r.left) / r.width) * this.W, ((ev.clientY - r.top) / r.height) * this.H];
  }

  bindPointer() {
    const ns = 'http://www.w3.org/2000/svg';
    this.rubber = document.createElementNS(ns, 'rect');
    this.line = document.createElementNS(ns, 'polyline');
    for (const shape of [this.rubber, this.line]) {
      shape.setAttribute('fill', 'rgba(255,255,255,0.18)');
      shape.setAttribute('stroke', '#fff');
      shape.setAttribute('stroke-width', '2');
      shape.setAttribute('vector-effect', 'non-scaling-stroke');
      shape.setAttribute('visibility', 'hidden');
      this.svg.append(shape);
    }
    this.wrap.addEventListener('pointerdown', (ev) => {
      if (ev.button !== 0) return;
      ev.preventDefault();
      this.root.focus();
      if (this.tool === 'rect') {
        this.dragFrom = this.toImage(ev);
        this.wrap.setPointerCapture(ev.pointerId);
      }
    });
    this.wrap.addEventListener('pointermove', (ev) => {
      const p = this.toImage(ev);
      if (this.tool === 'rect' && this.dragFrom) {
        const [a, b] = [this.dragFrom, p];
        this.rubber.setAttribute('x', Math.min(a[0], b[0]));
        this.rubber.setAttribute('y', Math.min(a[1], b[1]));
        this.rubber.setAttribute('width', Math.abs(a[0] - b[0]));
        this.rubber.setAttribute('height', Math.abs(a[1] - b[1]));
        this.rubber.setAttribute('visibility', 'visible');
      } else if (this.tool === 'poly' && this.draft.length) {
        this.drawDraft(p);
      }
    });
    this.wrap.addEventListener('pointerup', (ev) => {
      if (this.tool !== 'rect' || !this.dragFrom) return;
      const from = this.dragFrom;
      this.dragFrom = null;
      this.rubber.setAttribute('visibility', 'hidden');
      this.fillRect(from, this.toImage(ev));
    });
    this.wrap.addEventListener('click', (ev) => {
      if (this.tool !== 'poly' || ev.detail > 1) return;
      this.draft.push(this.toImage(ev));
      this.drawDraft();
    });
    this.wrap.addEventListener('dblclick', (ev) => {
      if (this.tool !== 'poly') return;
      ev.preventDefault();
      this.closePolygon();
    });
  }

  drawDraft(cursor) {
    const pts = cursor ? [...this.draft, cursor] : this.draft;
    this.line.setAttribute('points', pts.map((p) => p.join(',')).join(' '));
    this.line.setAttribute('visibility', pts.length ? 'visible' : 'hidden');
  }

  cancelDraft() {
    this.draft = [];
    this.dragFrom = null;
    if (this.line) this.line.setAttribute('visibility', 'hidden');
    if (this.rubber) this.rubber.setAttribute('visibility', 'hidden');
  }

  closePolygon() {
    const pts = this.draft.filter(
      (p, i, all) => i === 0 || Math.hypot(p[0] - all[i - 1][0], p[1] - all[i - 1][1]) > 0.5,
    );
    this.cancelDraft();
    if (pts.length >= 3) this.fillPolygon(pts);
  }

  onKey(ev) {
    const t = ev.target;
    if (t instanceof HTMLSelectElement || t instanceof HTMLInputElement || t instanceof HTMLTextAreaElement) return;
    if (ev.key === 'Escape') {
      if (this.draft.length || this.dragFrom) this.cancelDraft();
      ev.stopPropagation();
    } else if (ev.key === 'Enter' && this.tool === 'poly') this.closePolygon();
    else if (ev.key === 'Backspace' && this.draft.length) {
      this.draft.pop();
      this.drawDraft();
    } else if ((ev.ctrlKey || ev.metaKey) && ev.key.toLowerCase() === 'z') this.undo();
    else if (ev.key === 'r') this.setTool('rect');
    else if (ev.key === 'p') this.setTool('poly');
    else if (ev.key === 'e') this.setPaint('0');
    else return;
    ev.preventDefault();
  }

  // ---- saving
  async encodeMask(lut) {
    const c = document.createElement('canvas');
    c.width = this.W;
    c.height = this.H;
    const ctx = c.getContext('2d');
    const img = ctx.createImageData(this.W, this.H);
    const d = img.data;
    for (let i = 0; i < this.mask.length; i++) {
      const v = lut[this.mask[i]];
      d[4 * i] = d[4 * i + 1] = d[4 * i + 2] = v;
      d[4 * i + 3] = 255;
    }
    ctx.putImageData(img, 0, 0);
    const blob = await new Promise((resolve) => c.toBlob(resolve, 'image/png'));
    const url = await new Promise((resolve, reject) => {
      const r = new FileReader();
      r.onload = () => resolve(r.result);
      r.onerror = () => reject(r.error);
      r.readAsDataURL(blob);
    });
    return String(url).split(',')[1];
  }

  request() {
    const present = this.presentIds();
    if (!present.length) throw new Error('the mask is empty: paint the base (1) and its parts');
    if (!present.includes(1)) throw new Error('the base (1) is not painted: every mask shows the base');
    // ids consecutive: 1, then the parts in their order as 2, 3, ...
    const lut = new Uint8Array(256);
    const from = {};
    const parts = {};
    const confirmed = [];
    let next = 1;
    for (const id of present) {
      lut[id] = next;
      if (next >= 2) {
        const key = String(next);
        from[key] = this.opened.has(id) ? id : null;
        const m = this.motions.get(id) || { motion: '', set: false };
        if (m.motion) parts[key] = { motion: m.motion };
        if (m.set) confirmed.push(key);
      }
      next++;
    }
    const req = { id: this.id, parts, confirmed, from, mask_confirmed: this.maskConfirmed };
    if (this.categorySet) req.category = this.categorySelect.value;
    return { req, lut };
  }

  say(text, error = false) {
    this.status.textContent = text;
    this.status.classList.toggle('error', error);
  }

  async save() {
    let body;
    try {
      const { req, lut } = this.request();
      this.root.dataset.state = 'saving';
      this.saveButton.disabled = true;
      this.say('checking and writing…');
      req.mask = await this.encodeMask(lut);
      body = JSON.stringify(req);
    } catch (err) {
      this.root.dataset.state = 'ready';
      this.saveButton.disabled = false;
      return this.say(err.message || String(err), true);
    }
    let doc = null;
    try {
      const res = await fetch(`${API}/save`, {
        method: 'POST',
        headers: { 'Content-Type': 'application/json' },
        body,
      });
      doc = await res.json().catch(() => null);
      if (!res.ok) throw new Error((doc && doc.error) || `HTTP ${res.status}`);
    } catch (err) {
      this.root.dataset.state = 'error';
      this.saveButton.disabled = false;
      return this.say(`not saved: ${err.message || err}`, true);
    }
    const warn = doc.warnings && doc.warnings.length ? `\n${doc.warnings.join('\n')}` : '';
    this.say(`saved; converting again (job ${doc.job})…${warn}`);
    watchJob(this.id, doc.job, this);
  }
}

// ------------------------------------------------------------------ jobs and cards

async function watchJob(id, job, editor) {
  const card = cardOf(id);
  const note = () => cardOf(id)?.querySelector('.edit-note');
  if (card) card.dataset.editState = 'converting';
  for (;;) {
    let s;
    try {
      s = await getJSON(`${API}/status?job=${job}`);
    } catch (err) {
      if (note()) note().textContent = `lost the job: ${err.message}`;
      if (cardOf(id)) cardOf(id).dataset.editState = 'failed';
      return;
    }
    if (s.state === 'queued' || s.state === 'running') {
      const text = s.state === 'queued' ? 'waiting for another conversion…' : `converting: ${s.stage || 'starting'}…`;
      if (note()) note().textContent = text;
      if (editor && current === editor) editor.say(`saved; ${text}`);
      await new Promise((r) => setTimeout(r, POLL_MS));
      continue;
    }
    const fresh = await replaceCard(id, job);
    const r = s.result || {};
    const text =
      s.state === 'done'
        ? `converted again in ${s.seconds} s: ${r.status}, ${r.part_count} parts` +
          (r.mask_parts && r.mask_parts !== r.part_count ? ` (the mask shows ${r.mask_parts})` : '')
        : `conversion failed: ${s.message || r.reason || 'unknown reason'}`;
    const c = cardOf(id);
    if (c) {
      c.dataset.editState = s.state === 'done' ? 'done' : 'failed';
      const n = c.querySelector('.edit-note');
      if (n) n.textContent = text;
    }
    if (editor && current === editor) {
      if (s.state === 'done' && fresh) {
        editor.close();
        c?.scrollIntoView({ block: 'start' });
      } else {
        editor.root.dataset.state = 'error';
        editor.saveButton.disabled = false;
        editor.say(text, true);
      }
    }
    return;
  }
}

// Replace the card of `id` with the one of a fresh index.html (the server rewrote it).
async function replaceCard(id, version) {
  const old = cardOf(id);
  if (!old) return false;
  let doc;
  try {
    const res = await fetch(`index.html?v=${Date.now()}`, { cache: 'no-store' });
    if (!res.ok) throw new Error(`index.html: HTTP ${res.status}`);
    doc = new DOMParser().parseFromString(await res.text(), 'text/html');
  } catch (err) {
    console.error(err);
    return false;
  }
  const fresh = doc.getElementById(id);
  if (!fresh) return false;
  const card = document.importNode(fresh, true);
  const tag = `v=${version}.${Date.now()}`;
  for (const img of card.querySelectorAll('img[src]')) {
    const src = img.getAttribute('src');
    img.setAttribute('src', `${src}${src.includes('?') ? '&' : '?'}${tag}`);
  }
  const viewer = card.querySelector('.viewer[data-scene]');
  if (viewer) viewer.dataset.scene = `${viewer.dataset.scene}?${tag}`;
  document.dispatchEvent(new CustomEvent('gallery-card-replacing', { detail: { old } }));
  old.replaceWith(card);
  enableCard(card);
  document.dispatchEvent(new CustomEvent('gallery-card-replaced', { detail: { card } }));
  return true;
}

function enableCard(card) {
  for (const b of card.querySelectorAll('button.edit-mask')) {
    b.disabled = false;
    const n = b.parentElement.querySelector('.edit-note');
    if (n) n.textContent = '';
  }
}

async function openEditor(id) {
  if (current) current.close();
  const card = cardOf(id);
  const note = card?.querySelector('.edit-note');
  let state;
  try {
    state = await getJSON(`${API}/asset?id=${encodeURIComponent(id)}`);
  } catch (err) {
    if (note) note.textContent = `cannot open the editor: ${err.message}`;
    return;
  }
  if (state.pending_job) {
    if (note) note.textContent = 'a conversion of this asset is under way; wait for it';
    return;
  }
  current = new Editor(card, state);
  try {
    await current.open();
  } catch (err) {
    current.root.dataset.state = 'error';
    current.say(`cannot open the photo or mask: ${err.message || err}`, true);
  }
}

async function main() {
  if (location.protocol === 'file:') {
    document.body.dataset.editor = 'file';
    return; // the page's inline script says what to do
  }
  try {
    info = await getJSON(API);
  } catch {
    info = null;
  }
  const off = document.getElementById('editor-off');
  if (!info || !info.enabled) {
    const why = info
      ? info.reason
      : 'This server has no mask editor (a plain static server?); serve the folder with pact gallery OUT --serve to edit masks.';
    if (off) off.textContent = why;
    document.querySelectorAll('.edit-note').forEach((n) => (n.textContent = 'no mask editor on this server'));
    document.body.dataset.editor = 'off';
    return;
  }
  if (location.hostname !== '127.0.0.1') {
    const url = `http://127.0.0.1:${location.port}${location.pathname}`;
    if (off) off.textContent = `The mask editor answers only at ${url}; open the page there to edit masks.`;
    document.body.dataset.editor = 'off';
    return;
  }
  document.querySelectorAll('.card').forEach(enableCard);
  document.addEventListener('click', (ev) => {
    const b = ev.target.closest && ev.target.closest('button.edit-mask');
    if (b && !b.disabled) openEditor(b.dataset.asset);
  });
  document.body.dataset.editor = 'on';
}

main();
