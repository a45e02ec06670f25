// Rapier (WASM) loaded once, on first use. The -compat build carries its wasm inline as base64, so Vite
// bundles it into a chunk of the page's own JavaScript (fetched only when physics is switched on) and node
// imports it as is: nothing is fetched from anywhere else.
import type RAPIER from '@dimforge/rapier3d-compat';

export type Rapier = typeof RAPIER;

let ready: Promise<Rapier> | null = null;

export function loadRapier(): Promise<Rapier> {
  ready ??= import('@dimforge/rapier3d-compat').then(async (m) => {
    await m.default.init();
    return m.default;
  });
  return ready;
}
