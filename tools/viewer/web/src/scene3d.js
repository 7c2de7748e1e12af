// SPDX-License-Identifier: Apache-2.0
// The scene in 3D (three.js): the scene file's surfaces as slabs under their planes, the
// cliff's ground as two ledges with the gap between them (a bridge over the gap while the cliff
// holds, gone when it has dropped the HIP), the HIP with a small cartoon character standing on
// it, and the commanded force as an arrow from the HIP. Scene frame, metres, z up.
// A world (the hello's `world`: several devices in one scene) instead: every device's HIP in its
// own colour, labelled with its name, its commanded force as an arrow of that colour; the ball;
// each coupling as a line between its two HIPs.
import {
  AmbientLight,
  BoxGeometry,
  BufferAttribute,
  BufferGeometry,
  Color,
  DirectionalLight,
  Group,
  Line,
  LineBasicMaterial,
  Matrix4,
  Mesh,
  MeshLambertMaterial,
  MeshBasicMaterial,
  PerspectiveCamera,
  Quaternion,
  Scene,
  SphereGeometry,
  Sprite,
  SpriteMaterial,
  CanvasTexture,
  CylinderGeometry,
  Vector3,
  WebGLRenderer,
} from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { sceneParts } from './store.js';

const KIND_COLOURS = {
  wall: 0x8a99ad,
  friction: 0xa0785a,
  slippery: 0x7fd6f0,
  impact: 0xf0a050,
};
const FORCE_M_PER_N = 0.007; // arrow length per newton: 8 N is 5.6 cm
const TRAIL = 600;
/** A world's device colours, by device index (the plots and panels use the same). */
export const DEVICE_COLOURS = ['#d03030', '#2f6fd0', '#2a9d4a', '#b050c0'];

function basisFor(normal) {
  const n = new Vector3(...normal).normalize();
  const q = new Quaternion().setFromUnitVectors(new Vector3(0, 0, 1), n);
  return { n, q };
}

export class Scene3D {
  constructor(container, hello) {
    this.container = container;
    this.renderer = new WebGLRenderer({ antialias: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    container.appendChild(this.renderer.domElement);
    this.scene = new Scene();
    this.scene.background = new Color(0xf4f1ea);
    this.camera = new PerspectiveCamera(40, 1, 0.001, 10);
    this.camera.up.set(0, 0, 1);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.enableDamping = false;
    this.scene.add(new AmbientLight(0xffffff, 1.6));
    const sun = new DirectionalLight(0xffffff, 2.0);
    sun.position.set(0.3, -0.5, 1.0);
    this.scene.add(sun);

    const bounds = this.#bounds(hello);
    this.size = bounds.size;
    this.center = bounds.center;
    this.bridges = [];
    const parts = sceneParts(hello);
    for (const s of parts.surfaces) this.#addSurface(s);
    for (const c of parts.cliffs) this.#addCliff(c);
    this.world = hello.world ?? null;
    if (this.world) {
      this.#addWorld(hello);
    } else {
      this.#addHip();
      this.#addTrail();
    }

    const c = this.center;
    const d = this.size * 1.45;
    this.camera.position.set(c.x + d * 0.3, c.y - d * 1.0, c.z + d * 0.6);
    this.controls.target.copy(c);
    this.controls.update();
    this.resize();
    window.addEventListener('resize', () => this.resize());
  }

  /** Where to look: the device's workspace if the server knows it, else 12 cm around the scene. */
  #bounds(hello) {
    if (hello.workspace) {
      const min = new Vector3(...hello.workspace.min);
      const max = new Vector3(...hello.workspace.max);
      const center = min.clone().add(max).multiplyScalar(0.5);
      center.z = Math.min(center.z, 0.02);
      return { center, size: Math.max(0.06, Math.min(0.2, max.clone().sub(min).length() * 0.6)) };
    }
    const pts = [];
    const parts = sceneParts(hello);
    for (const s of parts.surfaces) pts.push(new Vector3(...s.point));
    for (const c of parts.cliffs) {
      const p = new Vector3(...c.point);
      const a = new Vector3(...c.axis);
      pts.push(p.clone().addScaledVector(a, (c.gap_min + c.gap_max) / 2));
    }
    const center = new Vector3();
    for (const p of pts) center.add(p);
    if (pts.length > 0) center.multiplyScalar(1 / pts.length);
    center.z += 0.01;
    return { center, size: 0.1 };
  }

  #slab(width, depth, thickness, colour, opacity = 0.85) {
    const mesh = new Mesh(
      new BoxGeometry(width, depth, thickness),
      new MeshLambertMaterial({ color: colour, transparent: opacity < 1, opacity }),
    );
    return mesh;
  }

  #addSurface(s) {
    const { n, q } = basisFor(s.normal);
    const half = this.size * 0.6;
    const thickness = 0.01;
    const slab = this.#slab(half * 2, half * 2, thickness, KIND_COLOURS[s.kind] ?? KIND_COLOURS.wall);
    // Centre the patch under the view centre's projection on the plane; the solid is on -n.
    const p = new Vector3(...s.point);
    const onPlane = this.center.clone().sub(n.clone().multiplyScalar(this.center.clone().sub(p).dot(n)));
    slab.quaternion.copy(q);
    slab.position.copy(onPlane).addScaledVector(n, -thickness / 2);
    slab.userData.kind = s.kind;
    this.scene.add(slab);
  }

  #addCliff(c) {
    const { n } = basisFor(c.normal);
    const a = new Vector3(...c.axis).normalize();
    const b = new Vector3().crossVectors(n, a).normalize(); // along the gap
    const p = new Vector3(...c.point);
    const half = this.size * 0.6;
    const thickness = 0.012;
    // The ground spans [lo, hi] along the axis around the gap; b spans the view.
    const lo = Math.min(c.gap_min - half, -half);
    const hi = Math.max(c.gap_max + half, half);
    const bCentre = this.center.clone().sub(p).dot(b);
    const group = new Group();
    const place = (mesh, s0, s1, offsetN) => {
      const mid = (s0 + s1) / 2;
      mesh.position.copy(p).addScaledVector(a, mid).addScaledVector(b, bCentre).addScaledVector(n, offsetN);
      // Orient the box's x along a, y along b, z along n.
      mesh.quaternion.setFromRotationMatrix(new Matrix4().makeBasis(a, b, n));
      group.add(mesh);
      return mesh;
    };
    const ledge = (s0, s1) => place(this.#slab(s1 - s0, half * 2, thickness, 0x7c8c6a, 0.95), s0, s1, -thickness / 2);
    ledge(lo, c.gap_min);
    ledge(c.gap_max, hi);
    // The pit: a dark box under the gap, so the gap reads as a hole.
    const pitDepth = 0.04;
    const pit = new Mesh(
      new BoxGeometry(c.gap_max - c.gap_min, half * 2, pitDepth),
      new MeshLambertMaterial({ color: 0x2a2622, transparent: true, opacity: 0.5 }),
    );
    place(pit, c.gap_min, c.gap_max, -pitDepth / 2 - 0.0005);
    // The bridge: what holds the HIP over the gap while the cliff is SUPPORTED.
    const bridge = new Mesh(
      new BoxGeometry(c.gap_max - c.gap_min, half * 2, 0.001),
      new MeshBasicMaterial({ color: 0xffd54a, transparent: true, opacity: 0.45 }),
    );
    place(bridge, c.gap_min, c.gap_max, -0.0005);
    this.bridges.push(bridge);
    this.scene.add(group);
  }

  #addHip() {
    this.hip = new Group();
    const hipDot = new Mesh(new SphereGeometry(0.0018, 16, 12), new MeshLambertMaterial({ color: 0xd03030 }));
    this.hip.add(hipDot);
    // The character stands on the HIP: a round body, big eyes, feet, a tail. It faces where
    // the HIP goes and squashes when an impact transient shakes it.
    const character = new Group();
    this.character = character;
    const skin = new MeshLambertMaterial({ color: 0xf2c14e });
    const body = new Mesh(new SphereGeometry(0.006, 24, 16), skin);
    body.scale.set(1, 0.9, 1.1);
    body.position.z = 0.0085;
    character.add(body);
    const head = new Mesh(new SphereGeometry(0.0045, 24, 16), skin);
    head.position.set(0.0015, 0, 0.0175);
    character.add(head);
    const white = new MeshLambertMaterial({ color: 0xffffff });
    const black = new MeshBasicMaterial({ color: 0x111111 });
    this.eyes = [];
    for (const side of [-1, 1]) {
      const eye = new Group();
      eye.add(new Mesh(new SphereGeometry(0.0017, 16, 12), white));
      const pupil = new Mesh(new SphereGeometry(0.0008, 12, 8), black);
      pupil.position.x = 0.0012;
      eye.add(pupil);
      eye.position.set(0.0048, side * 0.0018, 0.0192);
      character.add(eye);
      this.eyes.push(eye);
      const foot = new Mesh(new SphereGeometry(0.0022, 12, 8), new MeshLambertMaterial({ color: 0xc0602a }));
      foot.scale.set(1.5, 0.9, 0.6);
      foot.position.set(0.001, side * 0.003, 0.0012);
      character.add(foot);
      const ear = new Mesh(new SphereGeometry(0.002, 12, 8), skin);
      ear.position.set(0.0, side * 0.004, 0.0215);
      character.add(ear);
    }
    const tail = new Mesh(new CylinderGeometry(0.0005, 0.0008, 0.008, 8), new MeshLambertMaterial({ color: 0xc0602a }));
    tail.rotation.z = Math.PI / 2;
    tail.rotation.y = -0.7;
    tail.position.set(-0.0075, 0, 0.008);
    character.add(tail);
    this.hip.add(character);
    this.scene.add(this.hip);

    // The force arrow: a shaft and a head along +y of its group, drawn over everything (it is
    // a measurement, not an object in the scene), turned to the force's direction each frame.
    this.arrow = new Group();
    const red = new MeshBasicMaterial({ color: 0xd0213a, depthTest: false, transparent: true, opacity: 0.9 });
    this.arrowShaft = new Mesh(new CylinderGeometry(0.0007, 0.0007, 1, 12), red);
    this.arrowHead = new Mesh(new CylinderGeometry(0, 0.0022, 0.006, 16), red);
    this.arrowShaft.renderOrder = 10;
    this.arrowHead.renderOrder = 10;
    this.arrow.add(this.arrowShaft, this.arrowHead);
    this.arrow.visible = false;
    this.arrow.userData.direction = [0, 0, 0];
    this.arrow.userData.length = 0;
    this.scene.add(this.arrow);
    this.heading = 0;
  }

  /** A force arrow (a shaft and a head along +y of its group), drawn over everything. */
  #makeArrow(colour) {
    const arrow = new Group();
    const material = new MeshBasicMaterial({ color: colour, depthTest: false, transparent: true, opacity: 0.9 });
    const shaft = new Mesh(new CylinderGeometry(0.0007, 0.0007, 1, 12), material);
    const head = new Mesh(new CylinderGeometry(0, 0.0022, 0.006, 16), material);
    shaft.renderOrder = 10;
    head.renderOrder = 10;
    arrow.add(shaft, head);
    arrow.visible = false;
    arrow.userData = { shaft, head, direction: [0, 0, 0], length: 0 };
    this.scene.add(arrow);
    return arrow;
  }

  /** Points `arrow` from `from` along force `f` [N]; hidden below 1 mN. */
  #setArrow(arrow, from, f) {
    const magnitude = f.length();
    if (!(Number.isFinite(magnitude) && magnitude > 1e-3)) {
      arrow.visible = false;
      arrow.userData.direction = [0, 0, 0];
      arrow.userData.length = 0;
      return;
    }
    const dir = f.clone().divideScalar(magnitude);
    const length = Math.max(0.008, magnitude * FORCE_M_PER_N);
    const head = Math.min(0.006, length * 0.4);
    const { shaft, head: cone } = arrow.userData;
    arrow.position.copy(from);
    arrow.quaternion.setFromUnitVectors(new Vector3(0, 1, 0), dir);
    shaft.scale.set(1, length - head, 1);
    shaft.position.set(0, (length - head) / 2, 0);
    cone.scale.set(1, head / 0.006, 1);
    cone.position.set(0, length - head / 2, 0);
    arrow.visible = true;
    arrow.userData.direction = [dir.x, dir.y, dir.z];
    arrow.userData.length = length;
  }

  /** A text label that always faces the camera. */
  #label(text, colour) {
    const canvas = document.createElement('canvas');
    canvas.width = 256;
    canvas.height = 64;
    const ctx = canvas.getContext('2d');
    ctx.font = 'bold 40px system-ui, sans-serif';
    ctx.fillStyle = colour;
    ctx.textAlign = 'center';
    ctx.textBaseline = 'middle';
    ctx.fillText(text, 128, 32);
    const sprite = new Sprite(new SpriteMaterial({ map: new CanvasTexture(canvas), depthTest: false, transparent: true }));
    sprite.scale.set(0.024, 0.006, 1);
    sprite.renderOrder = 11;
    return sprite;
  }

  #addWorld(hello) {
    const world = hello.world;
    this.devices = world.devices.map((name, k) => {
      const colour = DEVICE_COLOURS[k % DEVICE_COLOURS.length];
      const hip = new Group();
      hip.add(new Mesh(new SphereGeometry(0.003, 20, 14), new MeshLambertMaterial({ color: colour })));
      const label = this.#label(name, colour);
      label.position.z = 0.009;
      hip.add(label);
      hip.visible = false; // until a frame places it
      this.scene.add(hip);
      return { name, index: k, colour, hip, arrow: this.#makeArrow(colour) };
    });
    this.ball = null;
    if (Number.isFinite(world.ball_radius)) {
      this.ball = new Mesh(
        new SphereGeometry(world.ball_radius, 32, 20),
        new MeshLambertMaterial({ color: 0xe0a030, transparent: true, opacity: 0.85 }),
      );
      this.ball.visible = false;
      this.scene.add(this.ball);
    }
    this.couplings = (world.couplings ?? []).map(([a, b]) => {
      const geometry = new BufferGeometry();
      geometry.setAttribute('position', new BufferAttribute(new Float32Array(6), 3));
      const line = new Line(geometry, new LineBasicMaterial({ color: 0x404040 }));
      line.frustumCulled = false;
      line.visible = false;
      line.userData = { a, b };
      this.scene.add(line);
      return line;
    });
    this.framed = false;
  }

  /** Device k's commanded force at frame i in the world frame: the trace has it in the device's
   *  own frame; the hello's rotation (if the scene was given) turns it. */
  worldForce(store, i, k) {
    const name = this.world.devices[k];
    const f = [store.get(i, `${name}.fx`), store.get(i, `${name}.fy`), store.get(i, `${name}.fz`)];
    const r = this.world.rotations ? this.world.rotations[k] : null;
    if (!r) return new Vector3(...f);
    const row = (j) => r[j][0] * f[0] + r[j][1] * f[1] + r[j][2] * f[2];
    return new Vector3(row(0), row(1), row(2));
  }

  #updateWorld(store, i) {
    const g = (name) => store.get(i, name);
    const centre = new Vector3();
    let placed = 0;
    for (const d of this.devices) {
      const p = new Vector3(g(`${d.name}.x`), g(`${d.name}.y`), g(`${d.name}.z`));
      const finite = Number.isFinite(p.x) && Number.isFinite(p.y) && Number.isFinite(p.z);
      d.hip.visible = finite;
      if (finite) {
        d.hip.position.copy(p);
        centre.add(p);
        placed += 1;
      }
      this.#setArrow(d.arrow, d.hip.position, this.worldForce(store, i, d.index));
      if (!finite) d.arrow.visible = false;
    }
    if (this.ball) {
      const b = new Vector3(g('ball.x'), g('ball.y'), g('ball.z'));
      this.ball.visible = Number.isFinite(b.x) && Number.isFinite(b.y) && Number.isFinite(b.z);
      if (this.ball.visible) this.ball.position.copy(b);
    }
    for (const line of this.couplings) {
      const a = this.devices[line.userData.a];
      const b = this.devices[line.userData.b];
      line.visible = Boolean(a && b && a.hip.visible && b.hip.visible);
      if (!line.visible) continue;
      const pos = line.geometry.attributes.position;
      pos.setXYZ(0, a.hip.position.x, a.hip.position.y, a.hip.position.z);
      pos.setXYZ(1, b.hip.position.x, b.hip.position.y, b.hip.position.z);
      pos.needsUpdate = true;
    }
    // The first frame places the camera on the devices (a world has no one workspace).
    if (!this.framed && placed > 0) {
      this.framed = true;
      centre.multiplyScalar(1 / placed);
      let spread = 0;
      for (const d of this.devices) if (d.hip.visible) spread = Math.max(spread, d.hip.position.distanceTo(centre));
      const size = Math.max(0.08, spread * 2.5);
      this.camera.position.set(centre.x + size * 0.3, centre.y - size * 1.3, centre.z + size * 0.7);
      this.controls.target.copy(centre);
      this.controls.update();
    }
    this.renderer.render(this.scene, this.camera);
  }

  #addTrail() {
    this.trailPositions = new Float32Array(TRAIL * 3);
    const geometry = new BufferGeometry();
    geometry.setAttribute('position', new BufferAttribute(this.trailPositions, 3));
    geometry.setDrawRange(0, 0);
    this.trail = new Line(geometry, new LineBasicMaterial({ color: 0x5060a0, transparent: true, opacity: 0.6 }));
    this.trail.frustumCulled = false;
    this.scene.add(this.trail);
  }

  resize() {
    const w = Math.max(1, this.container.clientWidth);
    const h = Math.max(1, this.container.clientHeight);
    this.renderer.setSize(w, h, false);
    this.renderer.domElement.style.width = '100%';
    this.renderer.domElement.style.height = '100%';
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
  }

  /** Shows frame i of the store. */
  update(store, i) {
    if (store.count === 0) {
      this.renderer.render(this.scene, this.camera);
      return;
    }
    if (this.world) {
      this.#updateWorld(store, i);
      return;
    }
    const g = (name) => store.get(i, name);
    const x = g('x');
    const y = g('y');
    const z = g('z');
    if (Number.isFinite(x) && Number.isFinite(y) && Number.isFinite(z)) this.hip.position.set(x, y, z);
    const vx = g('vx');
    const vy = g('vy');
    if (Math.hypot(vx, vy) > 0.01) this.heading = Math.atan2(vy, vx);
    this.character.rotation.z = this.heading;

    // Cartoon reactions: squash and stretch with the impact transient, wide eyes when fallen.
    const impact = store.runningImpact(i);
    const impactT = impact ? impact.t : NaN;
    let squash = 1;
    if (impact) squash = 1 - 0.25 * Math.exp(-impactT * 12) * Math.cos(impactT * 2 * Math.PI * 25);
    this.character.scale.set(1 / Math.sqrt(squash), 1 / Math.sqrt(squash), squash);
    const label = store.cliffLabel[i];
    const eyeScale = label === 3 ? 1.6 : 1;
    for (const eye of this.eyes) eye.scale.setScalar(eyeScale);
    for (const bridge of this.bridges) bridge.visible = label !== 3;

    const f = new Vector3(g('fx'), g('fy'), g('fz'));
    const magnitude = f.length();
    if (Number.isFinite(magnitude) && magnitude > 1e-3) {
      const dir = f.clone().divideScalar(magnitude);
      const length = Math.max(0.008, magnitude * FORCE_M_PER_N);
      const head = Math.min(0.006, length * 0.4);
      this.arrow.position.copy(this.hip.position);
      this.arrow.quaternion.setFromUnitVectors(new Vector3(0, 1, 0), dir);
      this.arrowShaft.scale.set(1, length - head, 1);
      this.arrowShaft.position.set(0, (length - head) / 2, 0);
      this.arrowHead.scale.set(1, head / 0.006, 1);
      this.arrowHead.position.set(0, length - head / 2, 0);
      this.arrow.visible = true;
      this.arrow.userData.direction = [dir.x, dir.y, dir.z];
      this.arrow.userData.length = length;
    } else {
      this.arrow.visible = false;
      this.arrow.userData.direction = [0, 0, 0];
      this.arrow.userData.length = 0;
    }

    // The last TRAIL frames' path (every other frame at most 1 kHz: 1.2 s).
    const step = 2;
    let n = 0;
    for (let k = i; k >= 0 && n < TRAIL; k -= step, ++n) {
      this.trailPositions[n * 3] = store.get(k, 'x');
      this.trailPositions[n * 3 + 1] = store.get(k, 'y');
      this.trailPositions[n * 3 + 2] = store.get(k, 'z');
    }
    this.trail.geometry.setDrawRange(0, n);
    this.trail.geometry.attributes.position.needsUpdate = true;
    this.renderer.render(this.scene, this.camera);
  }
}
