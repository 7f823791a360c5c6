// Loads a Lightloom bake (/bake/scene.glb) with three.js's GLTFLoader and draws its baked
// lighting from the glTF camera, unlit: `baseColor × light`, the light from COLOR_0 ×
// vertexLightScale (?variant=vertex) or from the LIGHTLOOM_lightmap RGBM texture on
// TEXCOORD_1 (?variant=lightmap). Renders into a float target and writes the linear pixels
// (RGBA float32, rows bottom to top, base64) into #result for the test to read.
import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";

const out = document.getElementById("result");
try {
  const params = new URLSearchParams(location.search);
  const variant = params.get("variant");
  const [width, height] = [Number(params.get("width")), Number(params.get("height"))];
  const renderer = new THREE.WebGLRenderer({ antialias: false });
  renderer.setPixelRatio(1);
  renderer.setSize(width, height, false);
  renderer.toneMapping = THREE.NoToneMapping;

  const gltf = await new GLTFLoader().loadAsync("/bake/scene.glb");
  const json = gltf.parser.json;
  const scale = json.scenes[json.scene ?? 0].extras.lightloom.vertexLightScale;

  // The lightmap extension, in a few lines: its texture from the GLB, undecoded bytes, RGBM
  // decoded in three's own lightmap path (value = rgb × a × range).
  const lightmaps = new Map();
  for (const [index, def] of (json.materials ?? []).entries()) {
    const ext = def.extensions?.LIGHTLOOM_lightmap;
    if (!ext) continue;
    const source = json.textures[ext.lightmapTexture.index].source;
    const view = json.images[source].bufferView;
    const bytes = await gltf.parser.getDependency("bufferView", view);
    const bitmap = await createImageBitmap(new Blob([bytes], { type: "image/png" }),
      { premultiplyAlpha: "none", colorSpaceConversion: "none" });
    const texture = new THREE.Texture(bitmap);
    texture.flipY = false;
    texture.channel = ext.lightmapTexture.texCoord;
    texture.colorSpace = THREE.NoColorSpace;
    texture.premultiplyAlpha = false;
    texture.generateMipmaps = false;
    texture.minFilter = texture.magFilter = THREE.LinearFilter;
    texture.needsUpdate = true;
    lightmaps.set(index, { texture, range: ext.range });
  }

  gltf.scene.traverse((object) => {
    if (!object.isMesh) return;
    const source = object.material;
    const index = gltf.parser.associations.get(source)?.materials;
    const material = new THREE.MeshBasicMaterial({ color: source.color.clone() });
    if (variant === "vertex") {
      material.vertexColors = true;
      material.color.multiplyScalar(scale);
    } else {
      const lightmap = lightmaps.get(index);
      material.lightMap = lightmap.texture;
      material.lightMapIntensity = lightmap.range * Math.PI;
      material.onBeforeCompile = (shader) => {
        shader.fragmentShader = shader.fragmentShader.replace(
          "lightMapTexel.rgb * lightMapIntensity", "lightMapTexel.rgb * lightMapTexel.a * lightMapIntensity");
      };
    }
    object.material = material;
  });

  const camera = gltf.cameras[0];
  camera.aspect = width / height;
  camera.updateProjectionMatrix();
  const scene = new THREE.Scene();
  scene.add(gltf.scene);
  scene.updateMatrixWorld(true);

  const target = new THREE.WebGLRenderTarget(width, height, { type: THREE.FloatType });
  renderer.setRenderTarget(target);
  renderer.setClearColor(0x000000, 0);
  renderer.clear();
  renderer.render(scene, camera);
  const pixels = new Float32Array(width * height * 4);
  renderer.readRenderTargetPixels(target, 0, 0, width, height, pixels);
  const bytes = new Uint8Array(pixels.buffer);
  let binary = "";
  for (let i = 0; i < bytes.length; i += 0x8000) binary += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  out.textContent = JSON.stringify({ width, height, pixels: btoa(binary) });
} catch (error) {
  out.textContent = JSON.stringify({ error: String(error && error.stack || error) });
}
