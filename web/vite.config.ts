// Builds the studio page into the Python package (src/kinetre/studio/static), served by `kinetre studio`.
// MediaPipe Pose is a classic script with wasm/tflite side files: they are copied from node_modules next to
// the page (no CDN), and served from node_modules by the dev server.
import { copyFileSync, createReadStream, existsSync, mkdirSync, writeFileSync } from 'node:fs';
import { join, resolve } from 'node:path';
import { defineConfig, type Plugin } from 'vite';

const POSE_DIR = resolve(__dirname, 'node_modules/@mediapipe/pose');
const POSE_FILES = [
  'pose.js',
  'pose_solution_packed_assets_loader.js',
  'pose_solution_packed_assets.data',
  'pose_solution_simd_wasm_bin.js',
  'pose_solution_simd_wasm_bin.wasm',
  'pose_solution_simd_wasm_bin.data',
  'pose_solution_wasm_bin.js',
  'pose_solution_wasm_bin.wasm',
  'pose_web.binarypb',
  'pose_landmark_lite.tflite',
  'pose_landmark_full.tflite',
];
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
const SOLUTIONS: [string, string, string[]][] = [['pose', POSE_DIR, POSE_FILES], ['face_mesh', FACE_DIR, FACE_FILES]];
const OUT_DIR = resolve(__dirname, '../src/kinetre/studio/static');

function mediapipeAssets(): Plugin {
  return {
    name: 'kinetre-mediapipe-assets',
    writeBundle() {
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
  plugins: [mediapipeAssets()],
});
