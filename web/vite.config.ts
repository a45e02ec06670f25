// Builds the studio page into the Python package (src/kinetre/studio/static), served by `kinetre studio`.
// MediaPipe's wasm files (tasks-vision, and the face_mesh solution's side files) are copied from node_modules
// next to the page (no CDN), as are the .task models that `make models` puts in .cache/models; the dev
// server serves them from there.
import { copyFileSync, createReadStream, existsSync, mkdirSync, readdirSync, writeFileSync } from 'node:fs';
import { join, resolve } from 'node:path';
import { defineConfig, type Plugin } from 'vite';

const FACE_DIR = resolve(__dirname, 'node_modules/@mediapipe/face_mesh');
const FACE_FILES = [
  'face_mesh.js',
  'face_mesh.binarypb',
  'face_mesh_solution_packed_assets_loader.js',
  'face_mesh_solution_packed_assets.data',
  'face_mesh_solution_simd_wasm_bin.js',
  'face_mesh_solution_simd_wasm_bin.wasm',
  'face_mesh_solution_simd_wasm_bin.data',
  'face_mesh_solution_wasm_bin.js',
  'face_mesh_solution_wasm_bin.wasm',
];
const TASKS_DIR = resolve(__dirname, 'node_modules/@mediapipe/tasks-vision/wasm');
const TASKS_FILES = readdirSync(TASKS_DIR);
const MODELS_DIR = resolve(__dirname, '../.cache/models');
const MODEL_FILES = ['pose_landmarker_full.task', 'hand_landmarker.task', 'face_landmarker.task'];
const SOLUTIONS: [string, string, string[]][] = [['face_mesh', FACE_DIR, FACE_FILES], ['tasks-vision', TASKS_DIR, TASKS_FILES]];

function checkModels(): void {
  const missing = MODEL_FILES.filter((f) => !existsSync(join(MODELS_DIR, f)));
  if (missing.length) throw new Error(`${MODELS_DIR}: missing ${missing.join(', ')} (run \`make models\` first)`);
}
const OUT_DIR = resolve(__dirname, '../src/kinetre/studio/static');

function mediapipeAssets(): Plugin {
  return {
    name: 'kinetre-mediapipe-assets',
    buildStart() {
      checkModels();
    },
    writeBundle() {
      mkdirSync(join(OUT_DIR, 'models'), { recursive: true });
      for (const file of MODEL_FILES) copyFileSync(join(MODELS_DIR, file), join(OUT_DIR, 'models', file));
      for (const [name, dir, files] of SOLUTIONS) {
        const target = join(OUT_DIR, 'mediapipe', name);
        mkdirSync(target, { recursive: true });
        for (const file of files) copyFileSync(join(dir, file), join(target, file));
      }
      writeFileSync(join(OUT_DIR, '.keep'), ''); // the folder is tracked by git through this file
    },
    configureServer(server) {
      for (const [name, dir, files] of SOLUTIONS) {
        server.middlewares.use(`/mediapipe/${name}`, (req, res, next) => {
          const file = (req.url ?? '').split('?')[0].replace(/^\//, '');
          if (!files.includes(file) || !existsSync(join(dir, file))) return next();
          if (file.endsWith('.wasm')) res.setHeader('Content-Type', 'application/wasm');
          createReadStream(join(dir, file)).pipe(res);
        });
      }
      server.middlewares.use('/models', (req, res, next) => {
        const file = (req.url ?? '').split('?')[0].replace(/^\//, '');
        if (!MODEL_FILES.includes(file) || !existsSync(join(MODELS_DIR, file))) return next();
        createReadStream(join(MODELS_DIR, file)).pipe(res);
      });
    },
  };
}

export default defineConfig({
  base: './',
  build: {
    outDir: OUT_DIR, emptyOutDir: true, chunkSizeWarningLimit: 2000, sourcemap: false,
    // the studio, and the face annotation page (served at /annotate/)
    rollupOptions: { input: { main: resolve(__dirname, 'index.html'), annotate: resolve(__dirname, 'annotate/index.html') } },
  },
  server: {
    proxy: {
      '/api': 'http://127.0.0.1:8000',
      '/ws': { target: 'ws://127.0.0.1:8000', ws: true },
    },
  },
  worker: { format: 'iife' }, // a classic worker: the Tasks wasm loader calls importScripts
  plugins: [mediapipeAssets()],
});
