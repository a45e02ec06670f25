// The Kinect v1 20-joint skeleton (the KinÊtre paper's tracker): joint names in the server's order and the 19 bones.

export const KINECT20_JOINTS = [
  'HipCenter', 'Spine', 'ShoulderCenter', 'Head',
  'ShoulderLeft', 'ElbowLeft', 'WristLeft', 'HandLeft',
  'ShoulderRight', 'ElbowRight', 'WristRight', 'HandRight',
  'HipLeft', 'KneeLeft', 'AnkleLeft', 'FootLeft',
  'HipRight', 'KneeRight', 'AnkleRight', 'FootRight',
] as const;

export const KINECT20_PARENTS = [-1, 0, 1, 2, 2, 4, 5, 6, 2, 8, 9, 10, 0, 12, 13, 14, 0, 16, 17, 18];

/** (parent, child) pairs. */
export const KINECT20_BONES: [number, number][] = KINECT20_PARENTS.flatMap((p, c) =>
  p >= 0 ? [[p, c] as [number, number]] : [],
);

export const JOINT_COUNT = KINECT20_JOINTS.length;

export const SUBSETS = [
  'whole body', 'left arm', 'right arm', 'arms', 'left leg', 'right leg', 'legs',
  'upper body', 'lower body', 'spine',
];
