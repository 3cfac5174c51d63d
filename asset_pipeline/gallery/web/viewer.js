// pact gallery: the interactive 3D view of each asset card (three.js, ES modules).
//
// Each `.viewer` element of index.html names its scene file (`data-scene`, written by
// asset_pipeline/gallery/page.py: links with their visual GLBs in the link frame, joints with
// parent, child, origin (4x4, row-major), axis, type and limits) and holds one range
// input per movable joint. A viewer loads when its card scrolls into view (or on a
// click) and at most MAX_LIVE viewers hold a WebGL context at once: the least recently
// used one is replaced by a still image of its last frame.
//
// Drag turns the object, right-drag pans; the wheel zooms in the full-window view
// (the ⤢ button; Esc leaves it) and scrolls the page elsewhere.
//
// URL query: ?asset=ID opens that asset's view full-window and loads it at once;
// &q=joint_a:0.5,joint_b:upper sets joints (a number, or lower/upper) through the
// sliders, as a person would; &view=photo looks through the photo's estimated camera. Every viewer tells its state in data-state
// (idle, loading, ready, error); <body> gets data-gallery-ready="1" once the view
// named by ?asset= (else every view in sight) has loaded and drawn, "error" when the
// named one failed (scripts/gallery_screenshot.sh waits for it). A card that the mask
// editor (editor.js) replaced after a re-conversion gets a new view
// (`gallery-card-replacing` / `gallery-card-replaced` events on document).

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const MAX_LIVE = 4;
const BACKGROUND = 0xeef1f5;
const VIEW_DIRECTION = new THREE.Vector3(1.0, 0.75, 0.65).normalize(); // as preview.png
const FOV = 35;

const live = []; // Viewer objects holding a WebGL context, least recently used first

function matrixOf(rows) {
  const m = new THREE.Matrix4();
  m.set(...rows);
  return m;
}

function fixed(group, rows) {
  group.matrixAutoUpdate = false;
  group.matrix.copy(matrixOf(rows));
  return group;
}

function formatValue(type, q) {
  if (type === 'prismatic') return `${q.toFixed(3)} m`;
  return `${((q * 180) / Math.PI).toFixed(1)}°`;
}

function disposeObject(root) {
  root.traverse((o) => {
    if (o.geometry) o.geometry.dispose();
    const mats = Array.isArray(o.material) ? o.material : o.material ? [o.material] : [];
    for (const m of mats) {
      for (const v of Object.values(m)) if (v && v.isTexture) v.dispose();
      m.dispose();
    }
  });
}

class Viewer {
  constructor(el) {
    this.el = el;
    this.stage = el.querySelector('.stage');
    this.sliders = [...el.querySelectorAll('input[type=range][data-joint]')];
    this.visible = false;
    this.state = 'idle';
    this.motions = new Map(); // joint name -> {group, type, axis}
    this.generation = 0;
    this.sliders.forEach((s) => {
      s.addEventListener('input', () => this.onSlider(s));
      this.showValue(s);
    });
    el.querySelector('.expand')?.addEventListener('click', (ev) => {
      ev.stopPropagation();
      this.setFocus(!this.el.classList.contains('focus'));
    });
    for (const b of el.querySelectorAll('button[data-pose]')) {
      b.addEventListener('click', () => this.setPose(b.dataset.pose));
    }
    el.querySelector('button[data-action=reset]')?.addEventListener('click', () => this.frame());
    el.querySelector('button[data-action=photo]')?.addEventListener('click', () => this.photoView());
    this.stage.addEventListener('click', () => {
      if (this.state === 'idle') this.activate();
    });
    this.setState('idle');
  }

  setState(s, message) {
    this.state = s;
    this.el.dataset.state = s;
    const note = this.stage.querySelector('.note');
    if (note) {
      if (s === 'loading') note.textContent = 'loading 3D view…';
      else if (s === 'error') note.textContent = message || '3D view failed';
      else if (s === 'idle') note.textContent = this.stage.querySelector('img.snapshot') ? '' : 'click to load the 3D view';
      else note.textContent = '';
      note.hidden = s === 'ready' || (s === 'idle' && !note.textContent);
    }
    this.sliders.forEach((x) => (x.disabled = s !== 'ready'));
    this.el.dispatchEvent(new CustomEvent('viewerstate', { bubbles: true, detail: s }));
  }

  setFocus(on) {
    document.querySelectorAll('.viewer.focus').forEach((v) => v !== this.el && v.classList.remove('focus'));
    this.el.classList.toggle('focus', on);
    document.body.classList.toggle('has-focus', on);
    const b = this.el.querySelector('.expand');
    if (b) {
      b.textContent = on ? '✕' : '⤢';
      b.title = on ? 'back to the gallery (Esc)' : 'full window';
    }
    if (this.controls) this.controls.enableZoom = on;
    if (on && this.state === 'idle') this.activate();
    this.resize();
  }

  touch() {
    const k = live.indexOf(this);
    if (k >= 0) live.splice(k, 1);
    live.push(this);
  }

  async activate() {
    if (this.state === 'loading' || this.state === 'ready') return this.touch();
    while (live.length >= MAX_LIVE) {
      const victim = live.find((v) => !v.visible && !v.el.classList.contains('focus')) || live[0];
      victim.release();
    }
    this.touch();
    const gen = ++this.generation;
    this.setState('loading');
    try {
      const sceneUrl = new URL(this.el.dataset.scene, document.baseURI);
      const res = await fetch(sceneUrl);
      if (!res.ok) throw new Error(`${this.el.dataset.scene}: HTTP ${res.status}`);
      const desc = await res.json();
      const built = await this.build(desc, sceneUrl);
      if (gen !== this.generation) return disposeObject(built); // released meanwhile
      this.photoCamera = desc.photo_camera || null;
      this.start(built);
      this.setState('ready');
    } catch (err) {
      console.error(err);
      if (gen === this.generation) {
        this.release(false);
        this.setState('error', `3D view failed: ${err.message || err}`);
      }
    }
  }

  async build(desc, sceneUrl) {
    const loader = new GLTFLoader();
    const root = new THREE.Group();
    const links = new Map();
    for (const link of desc.links) {
      const g = new THREE.Group();
      g.name = link.name;
      links.set(link.name, g);
    }
    const jobs = [];
    for (const link of desc.links) {
      for (const v of link.visuals) {
        const holder = fixed(new THREE.Group(), v.origin);
        links.get(link.name).add(holder);
        const url = new URL(v.url, sceneUrl);
        url.search = sceneUrl.search; // a re-converted card's version tag reaches its GLBs
        jobs.push(loader.loadAsync(url.href).then((gltf) => holder.add(gltf.scene)));
      }
    }
    this.motions = new Map();
    const children = new Set();
    for (const j of desc.joints) {
      const parent = links.get(j.parent);
      const child = links.get(j.child);
      if (!parent || !child) continue;
      const frame = fixed(new THREE.Group(), j.origin);
      const motion = new THREE.Group();
      frame.add(motion);
      motion.add(child);
      parent.add(frame);
      children.add(j.child);
      const axis = new THREE.Vector3(...j.axis);
      if (axis.lengthSq() > 0) axis.normalize();
      this.motions.set(j.name, { group: motion, type: j.type, axis, lower: j.lower, upper: j.upper });
    }
    for (const [name, g] of links) if (!children.has(name)) root.add(g);
    const results = await Promise.allSettled(jobs);
    const failed = results.filter((r) => r.status === 'rejected');
    if (failed.length === jobs.length && jobs.length > 0) throw failed[0].reason;
    if (jobs.length === 0) throw new Error('the asset has no visual meshes');
    failed.forEach((r) => console.warn('visual not loaded:', r.reason));
    root.traverse((o) => {
      if (o.isMesh) {
        const mats = Array.isArray(o.material) ? o.material : [o.material];
        for (const m of mats) {
          // exporters often leave metalness at 1; without an environment map that is black
          if (m.metalness !== undefined && !m.metalnessMap) m.metalness = Math.min(m.metalness, 0.3);
          m.side = THREE.DoubleSide; // open shells of scanned and imported meshes
        }
      }
    });
    return root;
  }

  start(root) {
    this.root = root;
    const scene = new THREE.Scene();
    scene.background = new THREE.Color(BACKGROUND);
    scene.add(new THREE.HemisphereLight(0xffffff, 0x9a9488, 2.2));
    const key = new THREE.DirectionalLight(0xffffff, 2.0);
    key.position.set(2, 1.2, 3);
    scene.add(key);
    const fill = new THREE.DirectionalLight(0xffffff, 0.6);
    fill.position.set(-2, -1.5, 1);
    scene.add(fill);
    scene.add(root);
    this.scene = scene;
    // bounds over the rest pose and the fully open pose, so opening stays in view
    const box = new THREE.Box3();
    for (const pose of ['upper', 'lower']) {
      this.applyPose(pose);
      root.updateMatrixWorld(true);
      box.expandByObject(root);
    }
    this.box = box;
    const size = box.getSize(new THREE.Vector3());
    const grid = new THREE.GridHelper(
      Math.max(size.x, size.y) * 2.4 || 1, 12, 0xc9ced6, 0xdde1e7,
    );
    grid.rotation.x = Math.PI / 2; // the grid lies in the xy plane (the floor, z up)
    grid.position.set((box.min.x + box.max.x) / 2, (box.min.y + box.max.y) / 2, box.min.z);
    scene.add(grid);
    this.sliders.forEach((s) => this.applySlider(s));

    const canvas = document.createElement('canvas');
    this.stage.querySelector('img.snapshot')?.remove();
    this.stage.prepend(canvas);
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    this.camera = new THREE.PerspectiveCamera(FOV, 1, 0.01, 100);
    this.camera.up.set(0, 0, 1);
    this.controls = new OrbitControls(this.camera, canvas);
    // in the list the wheel scrolls the page; the full-window view zooms with it
    this.controls.enableZoom = this.el.classList.contains('focus');
    this.controls.addEventListener('change', () => this.render());
    this.controls.addEventListener('start', () => (this.moved = true));
    this.frame();
    this.observer = new ResizeObserver(() => this.resize());
    this.observer.observe(this.stage);
    this.resize();
  }

  // the camera estimated for the photo: the view of photo_view.png
  photoView() {
    if (!this.camera || !this.photoCamera) return;
    const pos = new THREE.Vector3();
    const quat = new THREE.Quaternion();
    matrixOf(this.photoCamera.pose).decompose(pos, quat, new THREE.Vector3());
    const forward = new THREE.Vector3(0, 0, -1).applyQuaternion(quat);
    const centre = this.box.getCenter(new THREE.Vector3());
    const depth = Math.max(centre.clone().sub(pos).dot(forward), 0.05);
    this.camera.position.copy(pos);
    this.camera.fov = this.photoCamera.fov;
    this.camera.near = depth / 100;
    this.camera.far = depth * 20;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(pos).addScaledVector(forward, depth);
    this.controls.update();
    this.moved = true;
    this.render();
  }

  frame() {
    if (!this.camera) return;
    this.moved = false;
    this.camera.fov = FOV;
    const sphere = this.box.getBoundingSphere(new THREE.Sphere());
    const half = (FOV / 2) * (Math.PI / 180);
    const halfWidth = Math.atan(Math.tan(half) * this.camera.aspect); // narrow canvases
    const dist = (sphere.radius / Math.sin(Math.min(half, halfWidth))) * 1.02;
    this.camera.position.copy(sphere.center).addScaledVector(VIEW_DIRECTION, dist);
    this.camera.near = Math.max(dist / 100, 0.001);
    this.camera.far = dist * 10;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(sphere.center);
    this.controls.update();
    this.render();
  }

  resize() {
    if (!this.renderer) return;
    const w = Math.max(this.stage.clientWidth, 1);
    const h = Math.max(this.stage.clientHeight, 1);
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    if (!this.moved) this.frame(); // keep the whole object in view until the user turns it
    this.render();
  }

  render() {
    if (!this.renderer || this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      if (this.renderer) this.renderer.render(this.scene, this.camera);
    });
  }

  setJoint(name, q) {
    const m = this.motions.get(name);
    if (!m) return;
    if (m.type === 'prismatic') {
      m.group.quaternion.identity();
      m.group.position.copy(m.axis).multiplyScalar(q);
    } else if (m.type === 'revolute' || m.type === 'continuous') {
      m.group.position.set(0, 0, 0);
      m.group.quaternion.setFromAxisAngle(m.axis, q);
    }
  }

  applyPose(which) {
    for (const [name, m] of this.motions) this.setJoint(name, which === 'upper' ? m.upper : m.lower);
  }

  showValue(s) {
    const out = s.parentElement.querySelector('output');
    if (out) out.textContent = formatValue(s.dataset.type, Number(s.value));
  }

  applySlider(s) {
    this.setJoint(s.dataset.joint, Number(s.value));
  }

  onSlider(s) {
    this.showValue(s);
    this.applySlider(s);
    this.touch();
    this.render();
  }

  setPose(which) {
    for (const s of this.sliders) {
      s.value = which === 'upper' ? s.max : s.min;
      s.dispatchEvent(new Event('input'));
    }
  }

  release(snapshot = true) {
    this.generation++;
    const k = live.indexOf(this);
    if (k >= 0) live.splice(k, 1);
    if (this.renderer) {
      if (snapshot) {
        try {
          this.renderer.render(this.scene, this.camera);
          const img = new Image();
          img.className = 'snapshot';
          img.alt = 'last frame of the 3D view (click to load it again)';
          img.src = this.renderer.domElement.toDataURL('image/png');
          this.stage.prepend(img);
        } catch (err) {
          console.warn(err);
        }
      }
      this.observer?.disconnect();
      this.controls.dispose();
      disposeObject(this.scene);
      this.renderer.dispose();
      this.renderer.forceContextLoss();
      this.renderer.domElement.remove();
    }
    this.renderer = this.scene = this.camera = this.controls = this.root = null;
    this.motions = new Map();
    this.setState('idle');
  }
}

function parseQuery() {
  const p = new URLSearchParams(location.search);
  const q = new Map();
  for (const item of (p.get('q') || '').split(',')) {
    const k = item.lastIndexOf(':');
    if (k > 0) q.set(item.slice(0, k), item.slice(k + 1));
  }
  return { asset: p.get('asset'), q };
}

function setFromQuery(viewer, q) {
  for (const s of viewer.sliders) {
    if (!q.has(s.dataset.joint)) continue;
    const v = q.get(s.dataset.joint);
    s.value = v === 'upper' ? s.max : v === 'lower' ? s.min : v;
    s.dispatchEvent(new Event('input'));
  }
}

function afterPaint(fn) {
  requestAnimationFrame(() => requestAnimationFrame(fn));
}

function main() {
  if (location.protocol === 'file:') return; // the page's inline script explains what to do
  const body = document.body;
  const viewers = [...document.querySelectorAll('.viewer[data-scene]')].map((el) => new Viewer(el));
  const byElement = new Map(viewers.map((v) => [v.el, v]));
  const { asset, q } = parseQuery();
  const target = asset ? viewers.find((v) => v.el.dataset.asset === asset) : null;
  if (asset && !target) body.dataset.galleryReady = 'error';
  if (target) {
    target.el.addEventListener('viewerstate', (ev) => {
      if (ev.detail === 'ready') {
        setFromQuery(target, q);
        if (new URLSearchParams(location.search).get('view') === 'photo') target.photoView();
        afterPaint(() => (body.dataset.galleryReady = '1'));
      } else if (ev.detail === 'error') {
        body.dataset.galleryReady = 'error';
      }
    });
    target.setFocus(true);
  }
  // Without ?asset=: the page is ready once the views in sight have loaded (or failed).
  let observed = viewers.length === 0;
  const checkReady = () => {
    if (target || !observed) return;
    if (viewers.some((v) => v.state === 'loading')) delete body.dataset.galleryReady;
    else afterPaint(() => (body.dataset.galleryReady = viewers.some((v) => v.state === 'loading') ? '' : '1'));
  };
  document.addEventListener('viewerstate', checkReady);
  document.addEventListener('keydown', (ev) => {
    if (ev.key === 'Escape') document.querySelectorAll('.viewer.focus').forEach((el) => byElement.get(el).setFocus(false));
  });
  const io = new IntersectionObserver(
    (entries) => {
      for (const e of entries) {
        const v = byElement.get(e.target);
        v.visible = e.isIntersecting;
        if (!e.isIntersecting || target || v.state !== 'idle') continue;
        // load views coming into sight, unless as many others in sight already hold a context
        const busy = live.filter((x) => x.visible && x !== v).length >= MAX_LIVE;
        if (!busy) v.activate();
      }
      observed = true;
      checkReady();
    },
    { rootMargin: '100px' },
  );
  viewers.forEach((v) => io.observe(v.el));
  // The mask editor (editor.js) replaces a re-converted asset's card: drop the old view,
  // give the new card its own.
  document.addEventListener('gallery-card-replacing', (ev) => {
    for (const el of ev.detail.old.querySelectorAll('.viewer')) {
      const v = byElement.get(el);
      if (!v) continue;
      io.unobserve(el);
      byElement.delete(el);
      viewers.splice(viewers.indexOf(v), 1);
      v.release(false);
    }
  });
  document.addEventListener('gallery-card-replaced', (ev) => {
    for (const el of ev.detail.card.querySelectorAll('.viewer[data-scene]')) {
      const v = new Viewer(el);
      viewers.push(v);
      byElement.set(el, v);
      io.observe(el);
    }
  });
  checkReady();
}

main();
