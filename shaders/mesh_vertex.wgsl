// What every mesh pass hands from its vertices to its pixels (mesh.wgsl): where the vertex is,
// its frame and material, and the light its pass computed per vertex.

#define_import_path lightloom::mesh_vertex

struct VertexOut {
    @builtin(position) @invariant clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) tangent: vec4<f32>,
    @location(3) uv: vec2<f32>,
    @location(4) @interpolate(flat) material: u32,
    // The diffuse albedo: the vertex colour, times the material's albedo once the pass has read
    // it.
    @location(5) albedo: vec3<f32>,
    // Light computed per vertex (radiance toward the eye), diffuse and glossy; zeros where the
    // pass lights its pixels instead.
    @location(6) diffuse: vec3<f32>,
    @location(7) glossy: vec3<f32>,
    // How open the vertex is to the light it was lit by (normal_map.wgsl ndf_open_fraction).
    @location(8) open: vec3<f32>,
    // The vertex's mesh's texel layer (wavelet_pixel, area lights on textured meshes), or -1.
    @location(9) @interpolate(flat) layer: i32,
    // In the SH modes drawing their highlight per pixel (normal_map.wgsl
    // ndf_prefiltered_highlight), how open the vertex is to the light the highlight reflects
    // (mesh_prt.wgsl highlight_open).
    @location(10) highlight_open: vec3<f32>,
};
