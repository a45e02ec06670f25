// The face on an avatar: its chin on the avatar's neck (the paper's Fig. 7), per frame, from the bones
// the avatar map gives to Kinect's ShoulderCenter, Head and shoulders. Up is neck → head, the face's
// left is the avatar's left shoulder, so the face leans and turns with the body it rides on. Life size:
// the studio shows avatars 1.7 m tall. The avatar's own head stays, so the face is drawn over it like a
// mask (FacePuppet.place): avatars' heads differ too much (a bone's length says little) to fit inside.
import * as THREE from 'three';
import type { FaceAnchor } from './FacePuppet';

const CHIN_UP = 0.05;         // metres: the chin sits this far above the neck joint ...
const CHIN_FORWARD = 0.08;    // ... and this far in front of it

export function neckAnchor(bone: (kinectJoint: string) => THREE.Object3D | null): FaceAnchor | null {
  const [neck, head, left, right] = ['ShoulderCenter', 'Head', 'ShoulderLeft', 'ShoulderRight'].map(bone);
  if (!neck || !head || !left || !right) return null;
  const at = (o: THREE.Object3D) => o.getWorldPosition(new THREE.Vector3());
  const [n, h, l, r] = [at(neck), at(head), at(left), at(right)];
  const up = h.clone().sub(n);
  const length = up.length();
  if (length < 1e-6) return null;
  up.divideScalar(length);
  const side = l.sub(r);
  side.addScaledVector(up, -side.dot(up));
  if (side.lengthSq() < 1e-12) return null;
  side.normalize();
  const forward = new THREE.Vector3().crossVectors(side, up);
  const position = n.addScaledVector(up, CHIN_UP).addScaledVector(forward, CHIN_FORWARD);
  const quaternion = new THREE.Quaternion().setFromRotationMatrix(new THREE.Matrix4().makeBasis(side, up, forward));
  return { position, quaternion, scale: 1, overlay: true };
}
