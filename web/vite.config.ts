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
const OUT_DIR = resolve(__dirname, '../src/kinetre/studio/static');

function mediapipeAssets(): Plugin {
  return {
    name: 'kinetre-mediapipe-assets',
    writeBundle() {
      const target = join(OUT_DIR, 'mediapipe/pose');
      mkdirSync(target, { recursive: true });
      for (const file of POSE_FILES) copyFileSync(join(POSE_DIR, file), join(target, file));
      writeFileSync(join(OUT_DIR, '.keep'), ''); // the folder is tracked by git through this file
    },
    configureServer(server) {
      server.middlewares.use('/mediapipe/pose', (req, res, next) => {
        const file = (req.url ?? '').split('?')[0].replace(/^\//, '');
        if (!POSE_FILES.includes(file) || !existsSync(join(POSE_DIR, file))) return next();
        if (file.endsWith('.wasm')) res.setHeader('Content-Type', 'application/wasm');
        createReadStream(join(POSE_DIR, file)).pipe(res);
      });
    },
  };
}

export default defineConfig({
  base: './',
  build: { outDir: OUT_DIR, emptyOutDir: true, chunkSizeWarningLimit: 2000, sourcemap: false },
  server: {
    proxy: {
      '/api': 'http://127.0.0.1:8000',
      '/ws': { target: 'ws://127.0.0.1:8000', ws: true },
    },
  },
  plugins: [mediapipeAssets()],
});
