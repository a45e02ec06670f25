// The mesh's sphere proxies (KinÊtre paper, "Physics-based Interactions"): each sphere is centred on a mesh
// vertex and carried by that vertex's own 4 graph nodes and weights (Eq. 2), the formula the GPU skinning
// shader applies to the surface, so the proxies sit exactly where the drawn mesh is. Packed on the server
// (src/kinetre/physics/spheres.py).

export class SphereProxies {
  readonly count: number;
  readonly rest: Float32Array; // S × 3 centre vertices at rest, mesh frame
  readonly skinIndex: Uint16Array; // S × 4
  readonly skinWeight: Float32Array; // S × 4
  private readonly local: Float64Array;

  constructor(readonly radius: number, positions: Float32Array, skinIndex: Uint16Array, skinWeight: Float32Array,
              centres: Uint32Array) {
    this.count = centres.length;
    this.rest = new Float32Array(3 * this.count);
    this.skinIndex = new Uint16Array(4 * this.count);
    this.skinWeight = new Float32Array(4 * this.count);
    centres.forEach((v, s) => {
      this.rest.set(positions.subarray(3 * v, 3 * v + 3), 3 * s);
      this.skinIndex.set(skinIndex.subarray(4 * v, 4 * v + 4), 4 * s);
      this.skinWeight.set(skinWeight.subarray(4 * v, 4 * v + 4), 4 * s);
    });
    this.local = new Float64Array(3 * this.count);
  }

  /**
   * World centres: out[s] = placement · Σ_k w_k M_{j_k} v_s.
   * rows : N × 12 node matrices (top three rows, row-major, as in a transform block); null = rest pose.
   * placement : 4 × 4 column-major mesh → world matrix (three.js Matrix4.elements).
   */
  centres(rows: Float32Array | null, placement: ArrayLike<number>, out: Float32Array): Float32Array {
    const { rest, skinIndex, skinWeight, local } = this;
    for (let s = 0; s < this.count; s++) {
      const x = rest[3 * s], y = rest[3 * s + 1], z = rest[3 * s + 2];
      if (!rows) { local[3 * s] = x; local[3 * s + 1] = y; local[3 * s + 2] = z; continue; }
      let ox = 0, oy = 0, oz = 0;
      for (let k = 0; k < 4; k++) {
        const w = skinWeight[4 * s + k];
        if (w === 0) continue;
        const m = 12 * skinIndex[4 * s + k];
        ox += w * (rows[m] * x + rows[m + 1] * y + rows[m + 2] * z + rows[m + 3]);
        oy += w * (rows[m + 4] * x + rows[m + 5] * y + rows[m + 6] * z + rows[m + 7]);
        oz += w * (rows[m + 8] * x + rows[m + 9] * y + rows[m + 10] * z + rows[m + 11]);
      }
      local[3 * s] = ox; local[3 * s + 1] = oy; local[3 * s + 2] = oz;
    }
    const e = placement;
    for (let s = 0; s < this.count; s++) {
      const x = local[3 * s], y = local[3 * s + 1], z = local[3 * s + 2];
      out[3 * s] = e[0] * x + e[4] * y + e[8] * z + e[12];
      out[3 * s + 1] = e[1] * x + e[5] * y + e[9] * z + e[13];
      out[3 * s + 2] = e[2] * x + e[6] * y + e[10] * z + e[14];
    }
    return out;
  }

  /** The radius in the world: the placement's uniform scale times the packed radius. */
  worldRadius(placement: ArrayLike<number>): number {
    return this.radius * Math.hypot(placement[0], placement[1], placement[2]);
  }
}
