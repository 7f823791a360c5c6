// The one vertex and fragment entry of every mesh pass. Each pass is a module composed in by its
// shader def (render/src/shaders.rs): `light_vertex` adds its per-vertex light to the vertex
// every pass shares, `shade` turns what reaches a pixel into radiance.

#import lightloom::common::{MeshVertex, globals}
#import lightloom::mesh_vertex::VertexOut
#ifdef IRRADIANCE
#import lightloom::mesh_irradiance as lit
#endif
#ifdef PRT
#import lightloom::mesh_prt as lit
#endif
#ifdef WAVELET
#import lightloom::mesh_wavelet as lit
#endif
#ifdef RSL
#import lightloom::mesh_rsl as lit
#endif
#ifdef AREA
#import lightloom::mesh_area as lit
#endif

@vertex
fn vs_main(v: MeshVertex, @builtin(vertex_index) index: u32) -> VertexOut {
    var out: VertexOut;
    out.clip = globals.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.tangent = v.tangent;
    out.uv = v.uv;
    out.material = v.material;
    out.albedo = v.color;
    out.layer = -1;
    return lit::light_vertex(v, index, out);
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    return lit::shade(in, front);
}
