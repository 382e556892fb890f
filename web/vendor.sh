#!/usr/bin/env bash
# Copies the front-end files the binary embeds from node_modules (npm install)
# into vendor/, which is committed, so building radiosity needs no npm. Run
# after changing a version in package.json: npm install && ./vendor.sh
set -euo pipefail
cd "$(dirname "$0")"
src=node_modules/three
dst=vendor/three
rm -rf "$dst"
mkdir -p "$dst/build" "$dst/examples/jsm/controls" "$dst/examples/jsm/loaders" "$dst/examples/jsm/utils"
cp "$src/LICENSE" "$dst/"
cp "$src/build/three.module.js" "$src/build/three.core.js" "$dst/build/"
cp "$src/examples/jsm/controls/OrbitControls.js" "$dst/examples/jsm/controls/"
cp "$src/examples/jsm/loaders/GLTFLoader.js" "$dst/examples/jsm/loaders/"
cp "$src/examples/jsm/utils/BufferGeometryUtils.js" "$src/examples/jsm/utils/SkeletonUtils.js" "$dst/examples/jsm/utils/"
node -e 'console.log("vendored three " + require("./node_modules/three/package.json").version)'
