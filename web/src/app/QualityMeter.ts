// A user's live motion quality in a few words, from the figures the server measures over the last seconds
// of their frames (kinetre.motion.quality.LiveMeter): how much jitter cleaning removed, how often a foot is
// held on the floor, how far held feet stray, and the lag cleaning adds.
export interface MotionQuality {
  frames: number;
  fps: number | null; // the rate the frames came at
  jitter_tracked: number | null; // m/s², as tracked
  jitter: number | null; // m/s², as cleaned
  lag_ms: number | null;
  held: number | null; // share of frames with a foot held
  stray_cm: number | null; // 95th percentile of a held foot's distance from its hold
}

/** The meter's words for a user whose frames the server cleans by `cleaning` ("smoothing", "contact", both or
 * neither; absent from older servers, which meant both): what smoothing removed, or the jitter itself when
 * nothing smooths; the feet figures only while contact holds them. */
export function qualityMeter(q: MotionQuality | null | undefined, cleaning?: string[] | null): string {
  if (!q || q.jitter === null || q.jitter_tracked === null) return '';
  const smoothed = !cleaning || cleaning.includes('smoothing');
  const held = !cleaning || cleaning.includes('contact');
  const parts: string[] = [];
  if (smoothed && q.jitter_tracked > 0) {
    parts.push(`jitter −${Math.max(0, Math.round(100 * (1 - q.jitter / q.jitter_tracked)))} %`);
  } else if (!smoothed) parts.push(`jitter ${q.jitter.toFixed(1)} m/s²`);
  if (held && q.held !== null) parts.push(`feet held ${Math.round(100 * q.held)} %`);
  if (held && q.held && q.stray_cm !== null) parts.push(`slide ${q.stray_cm.toFixed(1)} cm`);
  if (smoothed && q.lag_ms !== null) parts.push(`lag ${Math.round(q.lag_ms)} ms`);
  if (!smoothed && !held) parts.push('as tracked');
  return parts.join(', ');
}
