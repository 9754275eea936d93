// Reads a DDS file with the independent parse-dds package and prints what it found as JSON (format, cube flag,
// size, and each face's and level's byte offset, length and size, faces outermost), for
// tests/ibl/test_prefilter_containers.cpp to check. parse-dds reads float RGBA (DXGI R32G32B32A32_FLOAT) cubes.
import { readFileSync } from 'node:fs';
import parse from 'parse-dds';

const bytes = readFileSync(process.argv[2]);
const dds = parse(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength));
console.log(JSON.stringify({
  format: dds.format, cubemap: dds.cubemap, shape: dds.shape,
  images: dds.images.map((i) => ({ offset: i.offset, length: i.length, shape: i.shape })),
}));
