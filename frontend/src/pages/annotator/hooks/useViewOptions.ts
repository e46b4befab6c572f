import { useCallback, useState } from "react";

/** How the player shows a frame (RGB picture or skeleton only, head blurred) and whether the
 * shortcuts help is open. Only annotators may unblur. */
export function useViewOptions(mayUnblur: boolean) {
  const [help, setHelp] = useState(false);
  const [showRgb, setShowRgb] = useState(true);
  const [blur, setBlur] = useState(true);
  return {
    help,
    showRgb,
    blur: blur || !mayUnblur,
    blurSetting: blur,
    setHelp,
    toggleHelp: useCallback(() => setHelp((h) => !h), []),
    toggleRgb: useCallback(() => setShowRgb((s) => !s), []),
    toggleBlur: useCallback(() => {
      if (mayUnblur) setBlur((b) => !b);
    }, [mayUnblur]),
  };
}
