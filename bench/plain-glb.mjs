// A GLB of a chosen size for the benches that store meshes (bench/token-holder.mjs,
// bench/model-routes.mjs): the proxy's upload checks read its counts, not its shape.

/// A GLB of `n` vertices (a multiple of 3) as an unindexed triangle list of float positions:
/// 12 bytes a vertex and some 300 bytes of JSON. The positions are zero, or with `scattered`
/// spread over [0, 1000) by a fixed sequence, so that gzip shrinks the mesh as little as it does
/// a real one's quantised, compressed buffers.
export function plainGlb(n, scattered = false) {
  const bin = Buffer.alloc(12 * n);
  let x = 1;
  for (let i = 0; scattered && i < 3 * n; i++) {
    x = (x * 1103515245 + 12345) % 2147483648;
    bin.writeFloatLE((x / 2147483648) * 1000, 4 * i);
  }
  const json = JSON.stringify({
    asset: { version: "2.0" },
    buffers: [{ byteLength: bin.length }],
    bufferViews: [{ buffer: 0, byteOffset: 0, byteLength: bin.length }],
    accessors: [
      { bufferView: 0, componentType: 5126, count: n, type: "VEC3", min: [0, 0, 0], max: scattered ? [1000, 1000, 1000] : [0, 0, 0] },
    ],
    meshes: [{ primitives: [{ attributes: { POSITION: 0 } }] }],
    nodes: [{ mesh: 0 }],
    scenes: [{ nodes: [0] }],
    scene: 0,
  });
  const padded = Buffer.from(json + " ".repeat((4 - (json.length % 4)) % 4));
  const total = 12 + 8 + padded.length + 8 + bin.length;
  const head = Buffer.alloc(12);
  head.write("glTF", 0);
  head.writeUInt32LE(2, 4);
  head.writeUInt32LE(total, 8);
  const chunk = (data, type) => {
    const h = Buffer.alloc(8);
    h.writeUInt32LE(data.length, 0);
    h.writeUInt32LE(type, 4);
    return Buffer.concat([h, data]);
  };
  return Buffer.concat([head, chunk(padded, 0x4e4f534a), chunk(bin, 0x004e4942)]);
}
