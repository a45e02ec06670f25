// Face blendshapes (MediaPipe's 52 ARKit names) on an avatar's morph targets: the page's side of
// src/kinetre/avatar/expressions.py `map_expressions`, from the avatar's glTF JSON; a Python test compares
// the two on one avatar. VRM expressions first (VRM 1.0 `VRMC_vrm.expressions`, VRM 0.x
// `VRM.blendShapeMaster`): one named like a blendshape takes its weight, a preset the mean of the
// blendshapes it stands for (VRM_PRESETS), each moving its bound morph targets by its bind weight. Otherwise
// morph targets named after a blendshape (`extras.targetNames`), matched ignoring case, punctuation and a
// prefix. Linear, so a matrix per mesh: weights = clip(W · blendshapes, 0, 1).

import TABLE from '../../../src/kinetre/data/blendshapes.json';

/** The blendshapes in FaceLandmarker's order (the package's data/blendshapes.json, as Python reads it). */
export const BLENDSHAPES: string[] = TABLE.names;
/** VRM 1.0 preset → the blendshapes whose mean drives it (the same table's vrm_presets). */
export const VRM_PRESETS: Record<string, string[]> = TABLE.vrm_presets;
/** VRM 0.x names of the same presets. */
const VRM0_NAMES: Record<string, string> = TABLE.vrm0_names;

const key = (name: string): string => String(name).toLowerCase().replace(/[^a-z0-9]/g, '');
const PRESETS = new Map<string, string[]>([
  ...Object.entries(VRM_PRESETS).map(([k, v]) => [key(k), v] as [string, string[]]),
  ...Object.entries(VRM0_NAMES).map(([old, now]) => [key(old), VRM_PRESETS[now]] as [string, string[]]),
]);

/** mesh index → W (targets × BLENDSHAPES.length); `how` the route taken ("vrm" or "names"). */
export interface ExpressionMap {
  matrices: Map<number, number[][]>;
  how: 'vrm' | 'names';
}

// the parts of a glTF document read here
interface GltfJson {
  meshes?: { primitives?: { targets?: unknown[]; extras?: { targetNames?: unknown } }[]; extras?: { targetNames?: unknown } }[];
  nodes?: { mesh?: number }[];
  extensions?: Record<string, unknown>;
}

/** How the blendshapes drive the morph targets of the avatar whose glTF JSON is `doc`. */
export function mapExpressions(doc: GltfJson, names: string[] = BLENDSHAPES): ExpressionMap {
  const counts = new Map<number, number>();
  (doc.meshes ?? []).forEach((mesh, m) => {
    const n = mesh.primitives?.[0]?.targets?.length ?? 0;
    if (n) counts.set(m, n);
  });
  const index = new Map<string, number>();
  names.forEach((n, i) => { if (!n.startsWith('_')) index.set(key(n), i); });
  const zeros = (n: number) => Array.from({ length: n }, () => new Array(names.length).fill(0));
  const groups = vrmExpressions(doc);
  if (groups.length) {
    const perLeftRight = groups.some(([g]) => key(g) === 'blinkl' || key(g) === 'blinkleft');
    const matrices = new Map([...counts].map(([m, n]) => [m, zeros(n)]));
    for (const [group, binds] of groups) {
      const k = key(group);
      const drive = new Array(names.length).fill(0);
      if (index.has(k)) drive[index.get(k)!] = 1;
      else if (PRESETS.has(k) || (k === 'blink' && !perLeftRight)) {
        const sources = PRESETS.get(k) ?? ['eyeBlinkLeft', 'eyeBlinkRight'];
        const used = sources.filter((s) => index.has(key(s))).map((s) => index.get(key(s))!);
        for (const i of used) drive[i] += 1 / used.length;
      }
      for (const [mesh, target, weight] of binds) {
        const w = matrices.get(mesh);
        if (w && target >= 0 && target < counts.get(mesh)!) w[target] = w[target].map((x, i) => x + weight * drive[i]);
      }
    }
    return { matrices, how: 'vrm' };
  }
  const matrices = new Map<number, number[][]>();
  for (const [m, n] of counts) {
    const w = zeros(n);
    targetNames(doc, m).slice(0, n).forEach((target, t) => {
      const k = key(target);
      let best = -1;
      for (const [name, i] of index) {
        if ((k === name || k.endsWith(name)) && (best < 0 || key(names[i]).length > key(names[best]).length)) best = i;
      }
      if (best >= 0) w[t][best] = 1; // the longest name: "mouthSmileLeft" over "mouthSmile"
    });
    matrices.set(m, w);
  }
  return { matrices, how: 'names' };
}

function targetNames(doc: GltfJson, m: number): string[] {
  const mesh = doc.meshes![m];
  for (const holder of [mesh, mesh.primitives?.[0]]) {
    const names = holder?.extras?.targetNames;
    if (Array.isArray(names)) return names.map(String);
  }
  return [];
}

type Bind = [number, number, number]; // mesh, morph target, weight 0..1

function vrmExpressions(doc: GltfJson): [string, Bind[]][] {
  const ext = doc.extensions ?? {};
  const out: [string, Bind[]][] = [];
  const vrm1 = (ext.VRMC_vrm as { expressions?: Record<string, Record<string, { morphTargetBinds?: { node?: number; index?: number; weight?: number }[] }>> } | undefined)?.expressions;
  if (vrm1 && typeof vrm1 === 'object') {
    for (const kind of ['preset', 'custom']) {
      for (const [name, expr] of Object.entries(vrm1[kind] ?? {})) {
        const binds: Bind[] = [];
        for (const b of expr?.morphTargetBinds ?? []) {
          const mesh = typeof b.node === 'number' ? doc.nodes?.[b.node]?.mesh : undefined;
          if (mesh !== undefined) binds.push([mesh, b.index ?? -1, b.weight ?? 1]);
        }
        out.push([name, binds]);
      }
    }
    return out;
  }
  const vrm0 = ext.VRM as { blendShapeMaster?: { blendShapeGroups?: { presetName?: string; name?: string; binds?: { mesh?: number; index?: number; weight?: number }[] }[] } } | undefined;
  for (const group of vrm0?.blendShapeMaster?.blendShapeGroups ?? []) {
    const preset = group.presetName;
    const name = preset && preset !== 'unknown' ? preset : group.name;
    out.push([String(name ?? ''), (group.binds ?? []).map((b) => [b.mesh ?? -1, b.index ?? -1, (b.weight ?? 100) / 100] as Bind)]);
  }
  return out;
}

/** mesh index → its morph target weights for one face (scores by blendshape name; missing ones are 0). */
export function expressionWeights(map: ExpressionMap, scores: Record<string, number>,
  names: string[] = BLENDSHAPES): Map<number, number[]> {
  const b = names.map((n) => (Number.isFinite(scores[n]) ? scores[n] : 0));
  const out = new Map<number, number[]>();
  for (const [m, w] of map.matrices) {
    if (!w.some((row) => row.some((x) => x !== 0))) continue;
    out.set(m, w.map((row) => Math.min(1, Math.max(0, row.reduce((s, x, i) => s + x * b[i], 0)))));
  }
  return out;
}

/** Something with morph target weights (a three.js Mesh). */
export interface MorphHolder { morphTargetInfluences?: number[] }

/** Set the weights of `expressionWeights` on the meshes of each glTF mesh index (all its primitives). */
export function applyExpressions(weights: Map<number, number[]>, meshes: Map<number, MorphHolder[]>): void {
  for (const [m, w] of weights) {
    for (const holder of meshes.get(m) ?? []) {
      const influences = holder.morphTargetInfluences;
      if (influences) for (let t = 0; t < Math.min(w.length, influences.length); t++) influences[t] = w[t];
    }
  }
}
