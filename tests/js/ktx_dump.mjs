// Reads a KTX2 file with the independent ktx-parse package and prints what it found as JSON (header, data format
// descriptor, key/value data, level byte offsets and the level data as little-endian words), for
// tests/ibl/test_prefilter_containers.cpp to check.
import { readFileSync } from 'node:fs';
import { read } from 'ktx-parse';

const path = process.argv[2];
const bytes = new Uint8Array(readFileSync(path));
const c = read(bytes);
const dfd = c.dataFormatDescriptor[0];
const keyValue = {};
for (const [k, v] of Object.entries(c.keyValue)) {
  keyValue[k] = typeof v === 'string' ? v : new TextDecoder().decode(v).replace(/\0$/, '');
}
const wordBytes = c.vkFormat === 97 ? 2 : 4;
const levels = c.levels.map((level) => {
  const view = new DataView(level.levelData.buffer, level.levelData.byteOffset, level.levelData.byteLength);
  const words = [];
  for (let i = 0; i + wordBytes <= level.levelData.byteLength; i += wordBytes) {
    words.push(wordBytes === 2 ? view.getUint16(i, true) : view.getUint32(i, true));
  }
  return {
    byteOffset: level.levelData.byteOffset,
    byteLength: level.levelData.byteLength,
    uncompressedByteLength: Number(level.uncompressedByteLength),
    words,
  };
});
console.log(JSON.stringify({
  vkFormat: c.vkFormat, typeSize: c.typeSize, pixelWidth: c.pixelWidth, pixelHeight: c.pixelHeight,
  pixelDepth: c.pixelDepth, layerCount: c.layerCount, faceCount: c.faceCount, levelCount: c.levels.length,
  supercompressionScheme: c.supercompressionScheme,
  dfd: {
    vendorId: dfd.vendorId, descriptorType: dfd.descriptorType, versionNumber: dfd.versionNumber,
    descriptorBlockSize: dfd.descriptorBlockSize, colorModel: dfd.colorModel, colorPrimaries: dfd.colorPrimaries,
    transferFunction: dfd.transferFunction, flags: dfd.flags, texelBlockDimension: dfd.texelBlockDimension,
    bytesPlane: dfd.bytesPlane, samples: dfd.samples,
  },
  keyValue, levels,
}));
