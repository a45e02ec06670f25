// The mesh as served by GET /api/mesh/{id}: base64 little-endian arrays → typed arrays.

export interface MeshPayloadJson {
  id: number;
  name: string;
  vertexCount: number;
  nodeCount: number;
  positions: string;
  normals: string;
  faces: string;
  skinIndex: string;
  skinWeight: string;
  nodes: string;
  nodeNormals: string;
  spheres: string;
  sphereRadius: number;
}

export interface MeshData {
  id: number;
  name: string;
  positions: Float32Array; // V × 3, metres, standing on y = 0
  normals: Float32Array; // V × 3
  faces: Uint32Array; // F × 3
  skinIndex: Uint16Array; // V × 4 graph nodes per vertex
  skinWeight: Float32Array; // V × 4, rows sum to 1
  nodes: Float32Array; // N × 3 node positions g_j
  nodeNormals: Float32Array; // N × 3
  spheres: Uint32Array; // S: the vertex at the centre of each physics proxy sphere
  sphereRadius: number; // their radius, mesh frame (metres before placement)
}

function bytes(b64: string): ArrayBuffer {
  const raw = atob(b64);
  const out = new Uint8Array(raw.length);
  for (let i = 0; i < raw.length; i++) out[i] = raw.charCodeAt(i);
  return out.buffer;
}

export function decodeMesh(json: MeshPayloadJson): MeshData {
  return {
    id: json.id,
    name: json.name,
    positions: new Float32Array(bytes(json.positions)),
    normals: new Float32Array(bytes(json.normals)),
    faces: new Uint32Array(bytes(json.faces)),
    skinIndex: new Uint16Array(bytes(json.skinIndex)),
    skinWeight: new Float32Array(bytes(json.skinWeight)),
    nodes: new Float32Array(bytes(json.nodes)),
    nodeNormals: new Float32Array(bytes(json.nodeNormals)),
    spheres: new Uint32Array(bytes(json.spheres)),
    sphereRadius: json.sphereRadius,
  };
}

export async function fetchMesh(url: string): Promise<MeshData> {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`cannot fetch the mesh ${url}: HTTP ${response.status}`);
  return decodeMesh((await response.json()) as MeshPayloadJson);
}
