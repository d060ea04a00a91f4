#!/usr/bin/env python3
"""Writes the malformed glTF/GLB corpus of tests/http_uploads.rs (malformed_files_get_4xx_and_the_server_stays_up)
and the fuzz seed corpus. Run from this directory: python3 make.py"""
import base64, json, struct

def bin48(nan=False, inf=False):
    pos = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    if nan:
        pos[4] = float("nan")
    if inf:
        pos[0] = float("inf")
    return struct.pack("<9f", *pos) + struct.pack("<3I", 0, 1, 2)

def gltf(data=None, byte_length=48, count=3, idx_count=3, nodes=None, buffer_index=0,
         uri="data", material=0, view_length=36):
    data = bin48() if data is None else data
    buf = {"byteLength": byte_length}
    if uri == "data":
        buf["uri"] = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
    elif uri is not None:
        buf["uri"] = uri
    return {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": nodes or [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": material}]}],
        "materials": [{"emissiveFactor": [1.0, 1.0, 1.0]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": count, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5125, "count": idx_count, "type": "SCALAR"},
        ],
        "bufferViews": [
            {"buffer": buffer_index, "byteOffset": 0, "byteLength": view_length},
            {"buffer": buffer_index, "byteOffset": 36, "byteLength": 12},
        ],
        "buffers": [buf],
    }

def glb(root, binary):
    j = json.dumps(root).encode()
    j += b" " * (-len(j) % 4)
    binary += b"\0" * (-len(binary) % 4)
    body = struct.pack("<I4s", len(j), b"JSON") + j + struct.pack("<I4s", len(binary), b"BIN\0") + binary
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body

def write(name, content):
    with open(name, "wb") as f:
        f.write(content if isinstance(content, bytes) else json.dumps(content).encode())

good_glb = glb(gltf(uri=None), bin48())
write("truncated.glb", good_glb[: len(good_glb) // 2])
write("truncated_header.glb", good_glb[:7])
write("wrong_magic.glb", b"gLTF" + good_glb[4:])
write("wrong_version.glb", good_glb[:4] + struct.pack("<I", 7) + good_glb[8:])
write("length_lies.glb", good_glb[:8] + struct.pack("<I", 0x7FFFFFF0) + good_glb[12:])
write("json_chunk_length_lies.glb", good_glb[:12] + struct.pack("<I", 0x7FFFFFF0) + good_glb[16:])
write("empty.glb", b"")
write("garbage.bin", bytes((i * 97 + 13) % 256 for i in range(300)))
write("not_json.gltf", b"{\"asset\": {\"version\": \"2.0\"}, \"scenes\": [")
write("json_array.gltf", b"[]")
write("deeply_nested.gltf", b"[" * 5000 + b"]" * 5000)
write("huge_accessor_count.gltf", gltf(count=4_000_000_000, idx_count=3_000_000_000))
write("huge_buffer_byte_length.gltf", gltf(byte_length=10**15))
write("data_uri_shorter_than_declared.gltf", gltf(byte_length=4096))
write("data_uri_longer_than_declared.gltf", gltf(byte_length=8))
write("bad_base64.gltf", {**gltf(), "buffers": [{"byteLength": 48, "uri": "data:application/octet-stream;base64,@@@notbase64@@@"}]})
write("cyclic_nodes.gltf", gltf(nodes=[{"mesh": 0, "children": [1]}, {"children": [0]}]))
write("self_child_node.gltf", gltf(nodes=[{"mesh": 0, "children": [0]}]))
write("nan_positions.gltf", gltf(data=bin48(nan=True)))
write("inf_positions.gltf", gltf(data=bin48(inf=True)))
write("missing_buffer.gltf", gltf(buffer_index=7))
write("no_buffers.gltf", {**gltf(), "buffers": []})
write("buffer_without_uri.gltf", gltf(uri=None))
write("external_uri.gltf", gltf(uri="../../../../etc/passwd"))
write("http_uri.gltf", gltf(uri="http://127.0.0.1:1/x.bin"))
write("view_beyond_buffer.gltf", gltf(view_length=4000))
write("index_out_of_range.gltf", gltf(data=bin48()[:36] + struct.pack("<3I", 0, 1, 99)))
write("material_out_of_range.gltf", gltf(material=42))
write("no_emitter.gltf", {**gltf(), "materials": [{}]})
write("nan_emission.gltf", {**gltf(), "materials": [{"emissiveFactor": [1.0, float("nan"), 1.0]}]})

# The same hostile contents in the binary container, and a few more shapes of each category.
write("truncated.gltf", json.dumps(gltf()).encode()[:200])
write("huge_accessor_count.glb", glb(gltf(uri=None, count=4_000_000_000, idx_count=3_000_000_000), bin48()))
def glb_with_extra_chunks(root, binary, extra):
    # Header, JSON chunk, `extra` empty unknown chunks, then the BIN chunk; lengths all true.
    j = json.dumps(root).encode()
    j += b" " * (-len(j) % 4)
    body = (struct.pack("<I4s", len(j), b"JSON") + j + struct.pack("<I4s", 0, b"XTRA") * extra
            + struct.pack("<I4s", len(binary), b"BIN\0") + binary)
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body

write("huge_chunk_count.glb", glb_with_extra_chunks(gltf(uri=None), bin48(), 10_000))
write("nan_positions.glb", glb(gltf(uri=None), bin48(nan=True)))
write("cyclic_nodes.glb", glb(gltf(uri=None, nodes=[{"mesh": 0, "children": [1]}, {"children": [0]}]), bin48()))
# Every node of level k is a child of both nodes of level k - 1: 2^40 paths to the last mesh if
# shared children were followed (glTF allows one parent per node).
shared = []
for k in range(40):
    children = [2 * k + 2, 2 * k + 3] if k < 39 else []
    shared += [{"mesh": 0, "children": children}, {"children": children}]
write("shared_children_nodes.gltf", {**gltf(), "nodes": shared[:-2] + [{"mesh": 0}, {"mesh": 0}]})

def glb_json_only(root):
    j = json.dumps(root).encode()
    j += b" " * (-len(j) % 4)
    body = struct.pack("<I4s", len(j), b"JSON") + j
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body

write("missing_bin_chunk.glb", glb_json_only(gltf(uri=None)))
write("bin_chunk_shorter_than_buffer.glb", glb(gltf(uri=None, byte_length=4096), bin48()))
# JSON has no NaN or infinity, but a number beyond f32 becomes infinite when read as f32.
write("inf_emission.gltf", {**gltf(), "materials": [{"emissiveFactor": [1e39, 1.0, 1.0]}]})
write("inf_emission_strength.gltf", {**gltf(), "extensionsUsed": ["KHR_materials_emissive_strength"],
    "materials": [{"emissiveFactor": [1.0, 1.0, 1.0],
                   "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 1e39}}}]})
write("inf_light_intensity.gltf", {**gltf(), "materials": [{}],
    "extensionsUsed": ["KHR_lights_punctual"],
    "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 1e39}]}},
    "nodes": [{"mesh": 0, "children": [1]}, {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [0.2, 0.2, 1.0]}]})
write("huge_translation.gltf", {**gltf(), "nodes": [{"mesh": 0, "translation": [1e39, 0.0, 0.0]}]})
# Accessor types the readers take on trust: indices must be unsigned integers, POSITION VEC3 floats.
write("float_indices.gltf", {**gltf(), "accessors": [gltf()["accessors"][0],
    {"bufferView": 1, "componentType": 5126, "count": 3, "type": "SCALAR"}]})
write("position_accessor_vec4_u8.gltf", {**gltf(), "accessors": [
    {"bufferView": 0, "componentType": 5121, "count": 3, "type": "VEC4"}, gltf()["accessors"][1]]})
