// The face template (MediaPipe's canonical face mesh) and its caricature morphs, as served by the studio
// (GET api/face/template, from kinetre.face: the page and `kinetre face` use the same numbers).

export interface FaceTemplate {
  vertices: Float32Array;   // 468 × 3, centimetres, +y up, +z out of the face
  uvs: Float32Array;        // 468 × 2 (v down)
  triangles: Uint16Array;   // 898 × 3
  weights: Float32Array;    // rigid-landmark weights of the alignment (0 for lips, lids, jaw)
  mirror: Int32Array;       // left/right vertex permutation
  chin: number;
  noseTip: number;
  morphNames: string[];
  morphs: Float32Array[];   // per morph: 468 × 3 displacements in cm
  presets: Record<string, number[]>;
}

interface Payload {
  vertices: number[]; uvs: number[]; triangles: number[]; weights: number[]; mirror: number[];
  chin: number; noseTip: number; morphNames: string[]; morphs: number[][]; presets: Record<string, number[]>;
}

let cached: Promise<FaceTemplate> | null = null;

export function fetchFaceTemplate(url = 'api/face/template'): Promise<FaceTemplate> {
  cached ??= fetch(url).then(async (r) => {
    if (!r.ok) throw new Error(`face template: HTTP ${r.status}`);
    const p = (await r.json()) as Payload;
    return {
      vertices: new Float32Array(p.vertices), uvs: new Float32Array(p.uvs), triangles: new Uint16Array(p.triangles),
      weights: new Float32Array(p.weights), mirror: new Int32Array(p.mirror), chin: p.chin, noseTip: p.noseTip,
      morphNames: p.morphNames, morphs: p.morphs.map((m) => new Float32Array(m)), presets: p.presets,
    };
  });
  return cached;
}
