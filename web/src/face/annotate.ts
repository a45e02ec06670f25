// The /annotate page: load a still image, superimpose the face template, pose and shape it, save the
// landmark file (and reload one). `kinetre face IMAGE --landmarks FILE` then rebuilds the face.
import './face.css';
import '../style.css';
import { type AnnotationPose, landmarkFile, poseFromLandmarks, project } from './Annotator';
import { type FaceTemplate, fetchFaceTemplate } from './FaceTemplate';
import { FaceTracker } from './FaceTracker';

const root = document.getElementById('annotate') as HTMLElement;
root.innerHTML = `
  <aside>
    <h1>Face annotation</h1>
    <div class="row"><label class="file">Image… <input type="file" id="image" accept="image/*"></label>
      <label class="file">Landmarks… <input type="file" id="load" accept=".json,application/json"></label></div>
    <div class="row"><button id="track" title="start from MediaPipe's fit">Fit with the tracker</button>
      <button id="save">Save landmarks</button> <a id="download" hidden>download</a></div>
    <div class="row"><label><input type="checkbox" id="flip"> show the flipped image and its mirrored landmarks</label></div>
    <div id="sliders"></div>
    <div id="message" role="status"></div>
    <p class="hint">Drag to move the template, mouse wheel to scale it; the sliders turn it and shape its
    features. Saving writes the 468 projected vertices (pixels, y down) and the mirrored copy for the
    left/right flipped image.</p>
  </aside>
  <main><canvas id="view"></canvas></main>`;
const $ = <T extends HTMLElement>(id: string) => root.querySelector(`#${id}`) as T;
const canvas = $<HTMLCanvasElement>('view');
const ctx = canvas.getContext('2d') as CanvasRenderingContext2D;
const message = $('message');
const say = (text: string, error = false) => { message.textContent = text; message.className = error ? 'error' : ''; };

let template: FaceTemplate | null = null;
let image: HTMLImageElement | null = null;
let imageName = '';
let pose: AnnotationPose = { scale: 10, yaw: 0, pitch: 0, roll: 0, x: 0, y: 0, weights: [0, 0, 0, 0, 0] };
let saved: object | null = null;
const tracker = new FaceTracker('../mediapipe/face_mesh/');
const sliders = new Map<string, HTMLInputElement>();

function addSlider(key: string, label: string, min: number, max: number, step: number, get: () => number, set: (v: number) => void) {
  const row = document.createElement('label');
  row.className = 'face-slider';
  row.textContent = label;
  const input = document.createElement('input');
  Object.assign(input, { type: 'range', min: String(min), max: String(max), step: String(step), id: `a-${key}` });
  input.value = String(get());
  input.addEventListener('input', () => { set(Number(input.value)); draw(); });
  row.appendChild(input);
  $('sliders').appendChild(row);
  sliders.set(key, input);
  (input as HTMLInputElement & { refresh: () => void }).refresh = () => { input.value = String(get()); };
}

function refreshSliders(): void {
  for (const s of sliders.values()) (s as HTMLInputElement & { refresh: () => void }).refresh();
}

function draw(): void {
  if (!image || !template) return;
  const flip = $<HTMLInputElement>('flip').checked;
  const w = image.naturalWidth, h = image.naturalHeight;
  const fit = Math.min((canvas.parentElement as HTMLElement).clientWidth / w, (canvas.parentElement as HTMLElement).clientHeight / h);
  canvas.width = Math.round(w * fit);
  canvas.height = Math.round(h * fit);
  ctx.save();
  if (flip) { ctx.translate(canvas.width, 0); ctx.scale(-1, 1); }
  ctx.drawImage(image, 0, 0, canvas.width, canvas.height);
  ctx.restore();
  let pts = project(template, pose);
  if (flip) {
    const m = new Float64Array(pts.length);
    for (let i = 0; i < pts.length / 2; i++) { const j = template.mirror[i]; m[2 * i] = w - pts[2 * j]; m[2 * i + 1] = pts[2 * j + 1]; }
    pts = m;
  }
  ctx.strokeStyle = 'rgba(120, 230, 255, 0.55)';
  ctx.lineWidth = 1;
  ctx.beginPath();
  const t = template.triangles;
  for (let k = 0; k < t.length; k += 3) {
    const [a, b, c] = [t[k], t[k + 1], t[k + 2]];
    ctx.moveTo(pts[2 * a] * fit, pts[2 * a + 1] * fit);
    ctx.lineTo(pts[2 * b] * fit, pts[2 * b + 1] * fit);
    ctx.lineTo(pts[2 * c] * fit, pts[2 * c + 1] * fit);
    ctx.closePath();
  }
  ctx.stroke();
  // the template's left-side vertices (the face's left, image right) in orange: on the flipped image they
  // stay on the image's right, as the tracker would label that face (a wrong mirror shows at once)
  ctx.fillStyle = '#ff8a00';
  for (let i = 0; i < pts.length / 2; i++) {
    if (template.vertices[3 * i] > 0.5) ctx.fillRect(pts[2 * i] * fit - 1, pts[2 * i + 1] * fit - 1, 2, 2);
  }
}

function centre(): void {
  if (!image || !template) return;
  // the template (≈ 15 cm wide) over the middle half of the image
  pose = { ...pose, scale: (0.5 * image.naturalWidth) / 15, x: image.naturalWidth / 2, y: image.naturalHeight / 2, yaw: 0, pitch: 0, roll: 0 };
}

async function loadImage(file: File | string, name: string): Promise<void> {
  const img = new Image();
  img.src = typeof file === 'string' ? file : URL.createObjectURL(file);
  await img.decode();
  image = img;
  imageName = name;
  centre();
  refreshSliders();
  draw();
  say(`${name}: ${img.naturalWidth}×${img.naturalHeight}; pose the template on the face`);
}

async function trackFit(): Promise<void> {
  if (!image || !template) return say('load an image first', true);
  say('tracking…');
  await tracker.init();
  const lm = await tracker.detect(image);
  if (!lm) return say('the tracker finds no face here: pose the template by hand', true);
  pose = poseFromLandmarks(template, lm);
  refreshSliders();
  draw();
  say('fitted by the tracker: adjust, then save');
}

function save(): object | null {
  if (!image || !template) { say('load an image first', true); return null; }
  saved = landmarkFile(template, pose, image.naturalWidth, image.naturalHeight, imageName);
  const a = $<HTMLAnchorElement>('download');
  if (a.href) URL.revokeObjectURL(a.href);
  a.href = URL.createObjectURL(new Blob([JSON.stringify(saved)], { type: 'application/json' }));
  a.download = `${imageName.replace(/\.[^.]*$/, '') || 'face'}.landmarks.json`;
  a.hidden = false;
  a.click();
  say(`saved ${a.download}: 468 landmarks and the mirrored copy`);
  return saved;
}

async function loadFile(file: File): Promise<void> {
  try {
    const doc = JSON.parse(await file.text()) as { format?: string; annotation?: AnnotationPose; width?: number; height?: number };
    if (doc.format !== 'kinetre-face-landmarks') throw new Error('not a kinetre landmark file');
    if (!doc.annotation) throw new Error('this file holds landmarks only, no template pose to edit');
    if (image && (doc.width !== image.naturalWidth || doc.height !== image.naturalHeight)) {
      throw new Error(`made for a ${doc.width}×${doc.height} image, this one is ${image.naturalWidth}×${image.naturalHeight}`);
    }
    pose = { ...doc.annotation, weights: [...doc.annotation.weights] };
    refreshSliders();
    draw();
    say(`${file.name} loaded`);
  } catch (err) {
    say(`${file.name}: ${(err as Error).message}`, true);
  }
}

void fetchFaceTemplate('../api/face/template').then((t) => {
  template = t;
  addSlider('scale', 'scale', 1, 80, 0.1, () => pose.scale, (v) => { pose.scale = v; });
  addSlider('yaw', 'yaw', -80, 80, 0.5, () => pose.yaw, (v) => { pose.yaw = v; });
  addSlider('pitch', 'pitch', -60, 60, 0.5, () => pose.pitch, (v) => { pose.pitch = v; });
  addSlider('roll', 'roll', -90, 90, 0.5, () => pose.roll, (v) => { pose.roll = v; });
  t.morphNames.forEach((name, k) => addSlider(name, name, -1, 1.5, 0.05, () => pose.weights[k], (v) => { pose.weights[k] = v; }));
  say('load an image (a photo the tracker misses, or any face)');
}).catch((err) => say(`template: ${(err as Error).message}`, true));

$<HTMLInputElement>('image').addEventListener('change', (e) => {
  const f = (e.target as HTMLInputElement).files?.[0];
  if (f) void loadImage(f, f.name);
});
$<HTMLInputElement>('load').addEventListener('change', (e) => {
  const f = (e.target as HTMLInputElement).files?.[0];
  if (f) void loadFile(f);
});
$('track').addEventListener('click', () => void trackFit());
$('save').addEventListener('click', () => save());
$('flip').addEventListener('change', () => draw());
window.addEventListener('resize', () => draw());

// drag to move, wheel to scale (about the cursor)
let drag: { x: number; y: number } | null = null;
const toImage = (e: MouseEvent) => {
  const k = image ? image.naturalWidth / canvas.width : 1;
  return { x: e.offsetX * k, y: e.offsetY * k };
};
canvas.addEventListener('pointerdown', (e) => { drag = toImage(e); canvas.setPointerCapture(e.pointerId); });
canvas.addEventListener('pointermove', (e) => {
  if (!drag) return;
  const p = toImage(e);
  pose.x += p.x - drag.x;
  pose.y += p.y - drag.y;
  drag = p;
  draw();
});
canvas.addEventListener('pointerup', () => { drag = null; });
canvas.addEventListener('wheel', (e) => {
  e.preventDefault();
  const p = toImage(e);
  const f = Math.exp(-e.deltaY * 0.001);
  pose.scale *= f;
  pose.x = p.x + (pose.x - p.x) * f;
  pose.y = p.y + (pose.y - p.y) * f;
  refreshSliders();
  draw();
}, { passive: false });

// window.kinetreAnnotate: for browser tests
(window as unknown as { kinetreAnnotate: object }).kinetreAnnotate = {
  ready: () => template !== null,
  loadImage: (url: string, name: string) => loadImage(url, name),
  trackFit,
  setPose: (p: Partial<AnnotationPose>) => { pose = { ...pose, ...p }; refreshSliders(); draw(); },
  pose: () => pose,
  save,
  loadText: (text: string, name = 'landmarks.json') => loadFile(new File([text], name)),
  message: () => message.textContent,
};
