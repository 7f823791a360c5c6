// Loads the bake's specular cube (/bake/environment_specular.ktx2, RGBA16F, 6 faces, mips) with
// three.js's KTX2Loader, reports what three made of it, and reads texels back through the GPU:
// a GLSL3 ShaderMaterial samples the cube map with `textureLod(cube, dir, level)` (nearest
// filtering, at texel centres) into a float target. Writes into #result
// { texture, levels, size, samples: [{ level, face, x, y, rgba }] } (y = 0: the file's first row).
import * as THREE from "three";
import { KTX2Loader } from "three/addons/loaders/KTX2Loader.js";

const out = document.getElementById("result");
try {
  const renderer = new THREE.WebGLRenderer({ antialias: false });
  // detectSupport() is required before loading; the Basis transcoder (served from tools/) is
  // only fetched for supercompressed files (vkFormat 0), not for raw RGBA16F.
  const loader = new KTX2Loader()
    .setTranscoderPath("/tools/node_modules/three/examples/jsm/libs/basis/")
    .detectSupport(renderer);
  const loaded = await loader.loadAsync("/bake/environment_specular.ktx2");
  const texture = {
    class: loaded.constructor.name,
    isCubeTexture: !!loaded.isCubeTexture,
    isDataTexture: !!loaded.isDataTexture,
    format: loaded.format, formatIsRGBA: loaded.format === THREE.RGBAFormat,
    type: loaded.type, typeIsHalfFloat: loaded.type === THREE.HalfFloatType,
    colorSpace: loaded.colorSpace,
    width: loaded.image.width, height: loaded.image.height,
    minFilter: loaded.minFilter, magFilter: loaded.magFilter,
    mipmaps: loaded.mipmaps.map((m) => ({ width: m.width, height: m.height, halves: m.data.length })),
  };

  // three r181 builds raw (non-Basis) KTX2 files as a 2D DataTexture whatever their faceCount:
  // each mip's data is the whole level (6 faces in a row) and only face +X would reach the GPU.
  // So the cube is assembled from three's own decoded levels, face f = the f-th sixth of a level,
  // as a CompressedCubeTexture with RGBAFormat: the object KTX2Loader builds for cube maps it
  // transcodes, which three uploads with texSubImage2D per face and level.
  const levels = loaded.mipmaps.length, size = loaded.image.width;
  const faces = [0, 1, 2, 3, 4, 5].map((f) => ({
    width: size, height: size,
    mipmaps: loaded.mipmaps.map((m) => {
      const n = m.width * m.height * 4;
      if (m.data.length !== 6 * n) throw new Error(`level ${m.width}: ${m.data.length} halves, not 6 faces`);
      return { data: m.data.subarray(f * n, (f + 1) * n), width: m.width, height: m.height };
    }),
  }));
  const cube = new THREE.CompressedCubeTexture(faces, THREE.RGBAFormat, THREE.HalfFloatType);
  cube.colorSpace = THREE.NoColorSpace;
  cube.minFilter = THREE.NearestMipmapNearestFilter;
  cube.magFilter = THREE.NearestFilter;
  cube.generateMipmaps = false;
  cube.needsUpdate = true;

  // Texel (x, y) of face f at size s → direction, by the GL/Vulkan/KTX table (sc, tc, ma):
  // u = 2(x+½)/s - 1 = sc/|ma|, v = 2(y+½)/s - 1 = tc/|ma|, faces +X -X +Y -Y +Z -Z.
  const direction = (f, x, y, s) => {
    const u = (2 * (x + 0.5)) / s - 1, v = (2 * (y + 0.5)) / s - 1;
    return [[1, -v, -u], [-1, -v, u], [u, 1, v], [u, -1, -v], [u, -v, 1], [-u, -v, -1]][f];
  };
  // Samples: every texel of levels ≤ 8 texels, otherwise an 8×8 grid (edges included).
  const samples = [];
  for (let level = 0; level < levels; level++) {
    const s = Math.max(1, size >> level);
    const coords = s <= 8 ? [...Array(s).keys()] : [...Array(8).keys()].map((i) => Math.round((i * (s - 1)) / 7));
    for (let face = 0; face < 6; face++)
      for (const y of coords) for (const x of coords) samples.push({ level, face, x, y });
  }

  // One pixel per sample: a float texture holds (direction, level), the shader looks it up.
  const width = 64, height = Math.ceil(samples.length / width);
  const query = new Float32Array(width * height * 4);
  samples.forEach((p, i) => query.set([...direction(p.face, p.x, p.y, size >> p.level), p.level], 4 * i));
  const queries = new THREE.DataTexture(query, width, height, THREE.RGBAFormat, THREE.FloatType);
  queries.needsUpdate = true;
  const material = new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3,
    uniforms: { cube: { value: cube }, queries: { value: queries } },
    vertexShader: "void main() { gl_Position = vec4(position.xy, 0.0, 1.0); }",
    fragmentShader: `
      uniform samplerCube cube;
      uniform highp sampler2D queries;
      out highp vec4 color;
      void main() {
        vec4 q = texelFetch(queries, ivec2(gl_FragCoord.xy), 0);
        color = textureLod(cube, q.xyz, q.w);
      }`,
  });
  const scene = new THREE.Scene();
  scene.add(new THREE.Mesh(new THREE.PlaneGeometry(2, 2), material));
  const target = new THREE.WebGLRenderTarget(width, height, { type: THREE.FloatType });
  renderer.setRenderTarget(target);
  renderer.render(scene, new THREE.Camera());
  const pixels = new Float32Array(width * height * 4);
  renderer.readRenderTargetPixels(target, 0, 0, width, height, pixels);
  samples.forEach((p, i) => (p.rgba = Array.from(pixels.subarray(4 * i, 4 * i + 4))));
  out.textContent = JSON.stringify({ texture, levels, size, samples });
} catch (error) {
  out.textContent = JSON.stringify({ error: String(error && error.stack || error) });
}
