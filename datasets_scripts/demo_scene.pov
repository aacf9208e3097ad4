// Offline demo scene for watergs: a strongly textured still life that COLMAP's SIFT can register.
// Rendered by make_demo_scene.sh, which declares on the command line:
//   Variant (1 or 2), CamX/CamY/CamZ (camera centre) and LookX/LookY/LookZ (look-at point),
//   all in POV-Ray's left-handed frame (y up). Watergs' world frame is (x, z, y) of this one.
// The horizontal field of view is FovDeg; square pixels (right vector = width/height).
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 5 }

#include "colors.inc"
#include "textures.inc"
#include "stones.inc"
#include "woods.inc"
#include "metals.inc"

#ifndef (Variant) #declare Variant = 1; #end
#ifndef (FovDeg) #declare FovDeg = 60; #end
#ifndef (CamX) #declare CamX = 0; #declare CamY = 2; #declare CamZ = -6.5; #end
#ifndef (LookX) #declare LookX = 0; #declare LookY = 0.6; #declare LookZ = 0; #end

camera {
  perspective
  location <CamX, CamY, CamZ>
  right x * image_width / image_height
  up y
  sky y
  angle FovDeg
  look_at <LookX, LookY, LookZ>
}

light_source { <12, 18, -9> color rgb <1.0, 0.97, 0.9> * 1.1 }
light_source { <-14, 12, 10> color rgb <0.6, 0.65, 0.75> shadowless }
sky_sphere { pigment { gradient y color_map { [0 color rgb <0.85, 0.9, 1.0>] [1 color rgb <0.35, 0.5, 0.85>] } } }

// Image maps shipped with povray-includes, tiled so small bitmaps still carry texture.
#macro ImagePigment(File, Scale)
  pigment { image_map { png File interpolate 2 } translate <-0.5, -0.5, 0> scale Scale }
#end

// A photo-like image stretched once over a Width x Height panel whose bottom edge is centred at the origin:
// no tiling, so no repeated texture that could give SIFT false matches.
#macro PanelImage(File, Width, Height)
  texture { pigment { image_map { png File once interpolate 2 } scale <Width, Height, 1> translate <-Width / 2, 0, 0> }
            finish { diffuse 0.8 } }
#end

// Variant 1's panels: eight textures, each used twice (on opposite sides of the ring).
#macro PanelTexture(Index, Width, Height)
  #switch (mod(Index, 8))
    #case (0) PanelImage("Mount1.png", Width, Height) #break
    #case (1) texture { pigment { brick color rgb 0.75 color rgb <0.6, 0.2, 0.1> brick_size <0.6, 0.25, 0.3> mortar 0.03 }
                        finish { diffuse 0.8 } }
              texture { pigment { granite color_map { [0 rgbt <0, 0, 0, 1>] [0.6 rgbt <0, 0, 0, 1>] [1 rgbt <0, 0, 0, 0.4>] } scale 0.7 } } #break
    #case (2) PanelImage("fract003.png", Width, Height) #break
    #case (3) texture { T_Stone8 scale 0.8 } #break
    #case (4) PanelImage("plasma3.png", Width, Height) #break
    #case (5) texture { pigment { Blue_Agate scale 0.6 } finish { diffuse 0.8 } } #break
    #case (6) PanelImage("mtmandj.png", Width, Height) #break
    #case (7) texture { T_Stone21 scale 0.7 } #break
  #end
#end

// Variant 2's panels: twelve different textures, so no two panels look alike (identical panels in a ring
// give SIFT matches between unrelated views).
#macro PanelTexture2(Index, Width, Height)
  #switch (Index)
    #case (0) PanelImage("Mount2.png", Width, Height) #break
    #case (1) texture { pigment { crackle color_map { [0 color rgb 0.1] [0.05 color rgb <0.9, 0.8, 0.5>] [1 color rgb <0.6, 0.4, 0.2>] } scale 0.3 } finish { diffuse 0.8 } } #break
    #case (2) PanelImage("povmap.png", Width, Height) #break
    #case (3) texture { T_Stone9 scale 0.8 } #break
    #case (4) PanelImage("bumpmap_.png", Width, Height) #break
    #case (5) texture { pigment { Sapphire_Agate scale 0.5 } finish { diffuse 0.8 } } #break
    #case (6) texture { pigment { brick color rgb <0.9, 0.9, 0.8> color rgb <0.2, 0.3, 0.6> brick_size <0.5, 0.2, 0.3> mortar 0.03 } finish { diffuse 0.8 } }
              texture { pigment { granite color_map { [0 rgbt <0, 0, 0, 1>] [0.5 rgbt <0, 0, 0, 1>] [1 rgbt <0.3, 0, 0, 0.3>] } scale 0.5 } } #break
    #case (7) texture { pigment { wrinkles turbulence 0.5 color_map { [0 color rgb <0.9, 0.2, 0.3>] [0.5 color rgb <1, 0.9, 0.3>] [1 color rgb <0.1, 0.5, 0.2>] } scale 0.4 } finish { diffuse 0.8 } } #break
    #case (8) PanelImage("fract003.png", Width, Height) #break
    #case (9) texture { T_Stone21 scale 0.6 } #break
    #case (10) texture { pigment { Brown_Agate scale 0.5 } finish { diffuse 0.8 } } #break
    #else texture { pigment { bozo turbulence 0.4 color_map { [0 color rgb <0.1, 0.2, 0.6>] [0.3 color rgb 0.9] [0.6 color rgb <0.5, 0.1, 0.5>] [1 color rgb <0.1, 0.6, 0.6>] } scale 0.25 } finish { diffuse 0.8 } }
  #end
#end

// A ring of vertical panels far behind the objects: gives every view distant texture.
#macro Backdrop(Radius, Height, Count, Phase)
  #local Width = 2 * Radius * tan(pi / Count) + 0.05;
  #for (Index, 0, Count - 1)
    box { <-Width / 2, 0, 0>, <Width / 2, Height, 0.3>
      #if (Variant = 1) PanelTexture(Index + Phase, Width, Height) #else PanelTexture2(Index, Width, Height) #end
      translate <0, 0, Radius> rotate y * (360 * Index / Count)
    }
  #end
#end

#if (Variant = 1)
  // Ground: checker of granite and marble tiles, with coloured turbulence inside each tile.
  disc { 0, y, 11
    texture {
      pigment { checker
        pigment { granite color_map { [0 color rgb <0.9, 0.8, 0.6>] [0.5 color rgb <0.5, 0.35, 0.2>] [1 color rgb <0.2, 0.15, 0.1>] } scale 0.6 }
        pigment { marble turbulence 0.9 color_map { [0 color rgb <0.3, 0.5, 0.35>] [0.5 color rgb <0.85, 0.9, 0.8>] [1 color rgb <0.2, 0.3, 0.25>] } scale 0.4 }
        scale 0.8 }
      finish { diffuse 0.85 specular 0.1 }
    }
  }
  Backdrop(10.5, 2.6, 16, 0)
  // Marble sphere with a sharp highlight: the view-dependent centre piece.
  sphere { <0, 0.85, 0>, 0.85 texture { pigment { Red_Marble scale 0.5 } finish { phong 0.7 phong_size 60 } } }
  // Wooden crate.
  box { <-0.6, 0, -0.6>, <0.6, 1.2, 0.6>
    texture { pigment { wood turbulence 0.15 color_map { [0 color rgb <0.85, 0.6, 0.3>] [0.4 color rgb <0.6, 0.35, 0.15>] [0.8 color rgb <0.3, 0.15, 0.05>] [1 color rgb <0.85, 0.6, 0.3>] } scale 0.08 rotate <80, 20, 5> } finish { specular 0.3 } }
    texture { pigment { checker color rgbt <0, 0, 0, 1> color rgbt <0.9, 0.9, 0.6, 0.5> scale 0.3 } }
    rotate y * 30 translate <-2.0, 0, 1.1> }
  // Column wrapped in a photo texture.
  cylinder { 0, 1.9 * y, 0.5
    texture { pigment { image_map { png "bumpmap_.png" map_type 2 interpolate 2 } scale <1, 0.95, 1> } finish { diffuse 0.8 } }
    translate <1.9, 0, 1.4> }
  // Checkered agate cone.
  cone { 0, 0.7, 1.6 * y, 0.0
    texture { pigment { checker pigment { Blue_Agate scale 0.3 } pigment { Brown_Agate scale 0.3 } scale 0.25 } finish { phong 0.4 } }
    translate <1.6, 0, -1.7> }
  // Jade torus.
  torus { 0.55, 0.22 texture { pigment { Jade scale 0.4 } finish { phong 0.5 } } rotate x * 20 translate <-1.6, 0.35, -1.7> }
  // Box faced with a fractal image.
  box { <-0.45, 0, -0.45>, <0.45, 0.9, 0.45>
    texture { ImagePigment("fract003.png", <0.9, 0.9, 1>) finish { diffuse 0.8 } }
    texture { pigment { gradient x color_map { [0 rgbt <1, 1, 1, 1>] [0.9 rgbt <1, 1, 1, 1>] [1 rgbt <0, 0, 0, 0.3>] } scale 0.3 } }
    rotate y * -25 translate <0.2, 0, 2.3> }
  // Polished metal ball: reflections make appearance depend on the view.
  sphere { <-0.5, 0.4, -2.4>, 0.4 texture { T_Brass_3C } }
  // Stone slab leaning on the crate.
  box { <-0.8, 0, -0.06>, <0.8, 1.0, 0.06> texture { T_Stone15 scale 0.6 } rotate x * -15 rotate y * 70 translate <-2.6, 0, -0.4> }
#else
  // Variant 2: hexagon tiles, stone stack, lettering, vase and blob; different palette.
  disc { 0, y, 11
    texture {
      pigment { hexagon
        pigment { bozo turbulence 0.6 color_map { [0 color rgb <0.8, 0.3, 0.2>] [0.5 color rgb <0.95, 0.85, 0.6>] [1 color rgb <0.3, 0.1, 0.1>] } scale 0.2 }
        pigment { granite color_map { [0 color rgb <0.2, 0.3, 0.5>] [1 color rgb <0.8, 0.85, 0.95>] } scale 0.8 }
        pigment { leopard color_map { [0 color rgb <0.1, 0.4, 0.1>] [1 color rgb <0.9, 0.95, 0.5>] } turbulence 0.5 scale 0.4 }
        scale 0.6 }
      finish { diffuse 0.85 }
    }
  }
  Backdrop(10.0, 3.0, 12, 3)
  // Stack of stone blocks.
  box { <-0.7, 0, -0.5>, <0.7, 0.6, 0.5> texture { T_Stone9 scale 0.5 } rotate y * 10 translate <-1.2, 0, 0.6> }
  box { <-0.5, 0, -0.4>, <0.5, 0.5, 0.4> texture { T_Stone4 scale 0.5 } rotate y * -20 translate <-1.2, 0.6, 0.6> }
  box { <-0.3, 0, -0.3>, <0.3, 0.4, 0.3> texture { T_Stone33 scale 0.4 } rotate y * 45 translate <-1.2, 1.1, 0.6> }
  // Lettering: sharp corners and strong gradients.
  text { ttf "timrom.ttf" "WATER" 0.3, 0
    texture { pigment { gradient y color_map { [0 color rgb <0.9, 0.6, 0.1>] [1 color rgb <0.2, 0.3, 0.9>] } } finish { phong 0.6 } }
    scale <1.2, 1.2, 1> translate <-1.6, 0, -1.6> rotate y * -15 }
  // Vase of rosewood.
  lathe { cubic_spline 8, <0, -0.1>, <0, 0>, <0.45, 0.1>, <0.6, 0.6>, <0.3, 1.1>, <0.35, 1.5>, <0.4, 1.6>, <0.4, 1.7>
    texture { Rosewood scale 0.2 finish { phong 0.6 phong_size 40 } } translate <1.6, 0, 1.2> }
  // Blob with a pink granite skin.
  blob { threshold 0.6
    sphere { <0, 0.5, 0>, 0.8, 1 } sphere { <0.5, 0.7, 0.2>, 0.6, 1 } sphere { <-0.3, 0.9, -0.3>, 0.5, 1 }
    texture { pigment { Pink_Granite scale 0.5 } finish { phong 0.5 } } translate <1.7, 0, -1.3> }
  // Chrome cylinder.
  cylinder { 0, 1.3 * y, 0.3 texture { T_Chrome_4C } translate <0.1, 0, 2.2> }
  // Plasma-mapped wedge.
  prism { linear_sweep linear_spline 0, 0.8, 4, <-0.6, -0.4>, <0.6, -0.4>, <0, 0.6>, <-0.6, -0.4>
    texture { pigment { image_map { png "plasma2.png" map_type 0 interpolate 2 } rotate x * 90 scale 0.5 } finish { diffuse 0.8 } }
    rotate y * 30 translate <0.3, 0, -0.2> }
#end
